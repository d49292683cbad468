"""Reinforcement learning on Pliant's environments: training with Stable-Baselines3
(:mod:`pliant.learn.training`), YAML configurations (:mod:`pliant.learn.config`), evaluation
(:mod:`pliant.learn.evaluate`), behaviour cloning (:mod:`pliant.learn.bc`), robust vectorised
workers (:mod:`pliant.learn.vec`), Ray scale-out (:mod:`pliant.learn.distributed`), and the
configuration-space graph of hierarchical agents (:mod:`pliant.learn.graph`).

This package sees environments only through Gymnasium (``gymnasium.make`` of the registered
ids); it never reaches into the simulation. Stable-Baselines3 and PyTorch load on first use of
``train`` (the command line starts without them).
"""

from pliant.learn.config import TrainConfig, load_config

_LAZY = {"train", "TrainResult", "parameters"}


def __getattr__(name: str):
    if name in _LAZY:
        from pliant.learn import training as module

        return getattr(module, name)
    raise AttributeError(f"module 'pliant.learn' has no attribute {name!r}")


__all__ = ["TrainConfig", "TrainResult", "load_config", "parameters", "train"]
