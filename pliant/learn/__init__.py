"""Reinforcement learning on Pliant's environments: training with Stable-Baselines3
(:mod:`pliant.learn.train`), YAML configurations (:mod:`pliant.learn.config`), evaluation
(:mod:`pliant.learn.evaluate`), behaviour cloning (:mod:`pliant.learn.bc`), robust vectorised
workers (:mod:`pliant.learn.vec`) and Ray scale-out (:mod:`pliant.learn.distributed`).

This package sees environments only through Gymnasium (``gymnasium.make`` of the registered
ids); it never reaches into the simulation.
"""

from pliant.learn.config import TrainConfig, load_config
from pliant.learn.train import TrainResult, parameters, train

__all__ = ["TrainConfig", "TrainResult", "load_config", "parameters", "train"]
