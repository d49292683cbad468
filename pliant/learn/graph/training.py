"""Train the configuration-space graph (or the plain-SAC baseline) with checkpoints, resume and
periodic evaluation, its evaluations logged to TensorBoard through Stable-Baselines3's logger
(``OUT/tb``), as ``pliant train`` logs them (the command: ``pliant graph train SCENE``)."""

from __future__ import annotations

import dataclasses
import json
import time
from pathlib import Path

from rich.console import Console

from pliant.errors import TrainingError
from pliant.files import read_checked, write_json

console = Console()

METHODS = ("graph", "convex", "convex_node", "sac")
SCENES = ("Corridor", "CartStemContact", "RodManipulator")


class GraphSettingsError(TrainingError):
    """A run's method or agent settings do not suit its scene: found before any training (the
    command line reports it as a usage error)."""


def build_controllers(method: str, scene) -> dict | None:
    """The internal agents' controllers of a method: the scene's convex controllers
    (``convex``), those kept inside their node (``convex_node``), or none (learned)."""
    return {"convex": scene.controllers, "convex_node": scene.node_controllers}.get(method)


def build_learner(method: str, scene, config, seed: int):
    from pliant.learn.graph import FlatSAC, GraphAgent

    env = scene.env
    if method == "sac":
        return FlatSAC(env.observation_space, env.action_space, config, seed=seed)
    controllers = build_controllers(method, scene)
    return GraphAgent(
        scene.graph, env.observation_space, env.action_space, config,
        controllers=controllers, experts=scene.experts, seed=seed,
    )  # fmt: skip


def train_run(
    scene_name: str,
    method: str,
    out: Path,
    *,
    steps: int,
    seed: int = 0,
    config: dict | None = None,
    env_kwargs: dict | None = None,
    eval_every: int = 600,
    eval_episodes: int = 5,
    resume: bool = True,
) -> list[dict]:
    """Train one learner; ``out`` holds ``checkpoint.pt`` and ``history.json`` (evaluations:
    steps, mean return, success rate, wall time), rewritten at every evaluation, and ``tb/``
    (TensorBoard: ``eval/mean_reward``, ``eval/success_rate``, ``time/wall_s`` against the
    environment steps). With ``resume`` an existing checkpoint is continued up to ``steps``."""
    from stable_baselines3.common.logger import configure

    from pliant.learn.graph import GraphConfig
    from pliant.learn.graph.scenes import make_scene

    if method not in METHODS:
        raise GraphSettingsError(f"method must be one of {METHODS}, got {method!r}")
    fields = {f.name for f in dataclasses.fields(GraphConfig)}
    unknown = set(config or {}) - fields
    if unknown:
        raise GraphSettingsError(f"unknown config keys {sorted(unknown)}; known: {sorted(fields)}")
    scene = make_scene(scene_name, **(env_kwargs or {}))
    if method.startswith("convex") and not build_controllers(method, scene):
        raise GraphSettingsError(
            f"{scene_name} has no {method} internal agents: use --method graph or sac"
        )
    learner = build_learner(method, scene, GraphConfig(**(config or {})), seed)
    out.mkdir(parents=True, exist_ok=True)
    checkpoint, history_file = out / "checkpoint.pt", out / "history.json"
    history = []
    if resume and checkpoint.exists():
        learner.load(checkpoint)
        history = read_checked(
            history_file, lambda p: json.loads(p.read_text())["evaluations"], "a graph history"
        )
        # The history is written before the checkpoint: a run killed between the two has an
        # evaluation more than its checkpoint, made again from it.
        history = [entry for entry in history if entry["steps"] <= learner.steps]
    start = time.perf_counter() - (history[-1]["wall_s"] if history else 0.0)
    logger = configure(str(out / "tb"), ["tensorboard"])

    def record(result: dict) -> None:
        history.append({**result, "wall_s": time.perf_counter() - start})
        logger.record("eval/mean_reward", result["return"])
        logger.record("eval/success_rate", result["success"])
        logger.record("time/wall_s", history[-1]["wall_s"])
        logger.dump(result["steps"])
        meta = {"scene": scene_name, "method": method, "seed": seed, "config": config or {},
                "env": env_kwargs or {}}  # fmt: skip
        write_json(history_file, {**meta, "evaluations": history})
        learner.save(checkpoint)  # after the history (see the resume above)
        console.print(f"{method} seed {seed}: {result}")

    try:
        learner.learn(
            scene.env, steps, eval_every=eval_every, eval_episodes=eval_episodes, callback=record
        )
    finally:
        logger.close()
    return history
