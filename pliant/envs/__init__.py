"""Gymnasium environments of Pliant's robots, registered as ``pliant/<Name>-v0``.

``import pliant.envs`` registers them; then ``gymnasium.make("pliant/Diamond-v0")``. Each is a
thin layer over a robot builder (:mod:`pliant.robots`); :mod:`pliant.envs.base` holds what
they share: one simulation config (:class:`pliant.envs.config.SimulationConfig`: ``dt``,
``substeps``, ``action_type``, ``tangent``, ``render_mode``, given as ``config=`` or as
keywords), action maps that turn actions into commands (:mod:`pliant.envs.actions`), ramped
commands, exact save/restore (``env.unwrapped.get_state()`` /
``set_state()``), divergence handling (the episode is truncated, ``info["diverged"]`` says
why) and rendering.

Vectorised stepping: numba's OpenMP kernels abort a child process forked after they ran in
the parent ("fork() called from a process already using GNU OpenMP"), so worker processes
must start with "spawn" or "forkserver": :func:`make_vector_env` and
:func:`make_subproc_vec_env` do so by default.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial

import gymnasium as gym

from pliant.envs.base import EnvSnapshot, EnvStateError, SoftRobotEnv
from pliant.envs.config import SimulationConfig


@dataclass(frozen=True)
class EnvSpec:
    name: str
    entry_point: str
    max_episode_steps: int
    #: keyword arguments of a small, fast variant (tests, quick demos).
    quick: dict


ENVS: dict[str, EnvSpec] = {}


def _register(name: str, where: str, max_episode_steps: int, **quick) -> None:
    """Register ``pliant/<name>-v0``, the class `where` (``module:Class`` in pliant.envs)."""
    entry_point = f"pliant.envs.{where}"
    ENVS[name] = EnvSpec(name, entry_point, max_episode_steps, quick)
    env_id = f"pliant/{name}-v0"
    if env_id not in gym.registry:
        gym.register(id=env_id, entry_point=entry_point, max_episode_steps=max_episode_steps)


_register("Diamond", "diamond:DiamondEnv", 50, mesh_size=20.0)
_register("Trunk", "trunk:TrunkEnv", 250, mesh_size=8.0, settle_steps=5)
_register("CartStemContact", "cartstem:CartStemContactEnv", 30, substeps=10, cells=6)
_register("SimpleMaze", "maze:SimpleMazeEnv", 50, substeps=4)
_register("Maze", "maze:MazeEnv", 250, substeps=2, mesh_size=8.0)
_register("Multigait", "multigait:MultigaitEnv", 6, substeps=4, mesh_size=10.0)
_register("MultigaitProxy", "multigait_proxy:MultigaitProxyEnv", 12, substeps=20)
_register("TrunkPushProxy", "trunk_push_proxy:TrunkPushProxyEnv", 10, substeps=5, settle_steps=5)
_register("TrunkCup", "trunk_cup:TrunkCupEnv", 250, settle_steps=5)
_register("TrunkPush", "trunk_push:TrunkPushEnv", 10, substeps=5, settle_steps=5)
_register("RodManipulator", "rod_manipulator:RodManipulatorEnv", 30, mesh_size=8.0, substeps=4)
_register("CatchTheObject", "catch_object:CatchTheObjectEnv", 30, mesh_size=8.0, substeps=4)
_register("CartStem", "cartstem_free:CartStemEnv", 80, substeps=4)
_register("StemPendulum", "stem_pendulum:StemPendulumEnv", 50, substeps=4)
_register(
    "BubbleMotion",
    "bubble_motion:BubbleMotionEnv",
    20,
    substeps=3,
    mesh_size=10.0,
    top_mesh_size=6.0,
)
_register(
    "TrunkSpaceDebris",
    "trunk_space_debris:TrunkSpaceDebrisEnv",
    50,
    substeps=3,
    cube_sizes=(20.0, 30.0),
)
_register("Gripper", "gripper:GripperEnv", 250, substeps=2, mesh_size=12.0)
_register(
    "ReducedMultigait",
    "reduced_multigait:ReducedMultigaitEnv",
    6,
    substeps=4,
    mesh_size=10.0,
    training={"sequences": 0, "phase": 0.2},
)


def make(env_id: str, **kwargs) -> gym.Env:
    """``gymnasium.make`` that registers Pliant's environments first: the factory of worker
    processes, which start without them."""
    return gym.make(env_id, **kwargs)


def get_state(env: gym.Env) -> EnvSnapshot:
    """Snapshot of an environment, wrapped or not (``env.unwrapped.get_state()``)."""
    return env.unwrapped.get_state()


def set_state(env: gym.Env, snapshot: EnvSnapshot) -> None:
    """Restore a snapshot into an environment and its wrappers: the unwrapped environment, and
    the step counter of a TimeLimit (the snapshot's step count), so that the episode ends where
    it would have."""
    env.unwrapped.set_state(snapshot)
    layer = env
    while isinstance(layer, gym.Wrapper):
        if isinstance(layer, gym.wrappers.TimeLimit):
            layer._elapsed_steps = snapshot.elapsed_steps
        layer = layer.env


def env_ids() -> list[str]:
    return [f"pliant/{name}-v0" for name in ENVS]


def make_vector_env(
    env_id: str, n: int, *, asynchronous: bool = True, context: str = "spawn", **kwargs
):
    """n copies of an environment in a Gymnasium vector env; asynchronous workers start with
    `context` ("spawn" or "forkserver": see the module docstring)."""
    factories = [partial(make, env_id, **kwargs) for _ in range(n)]
    if asynchronous:
        return gym.vector.AsyncVectorEnv(factories, context=context)
    return gym.vector.SyncVectorEnv(factories)


def make_subproc_vec_env(
    env_id: str, n: int, *, start_method: str = "spawn", seed: int | None = None, **kwargs
):
    """Stable-Baselines3's SubprocVecEnv of n copies, started with `start_method`."""
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import SubprocVecEnv

    return make_vec_env(
        partial(make, env_id),
        n_envs=n,
        seed=seed,
        env_kwargs=kwargs,
        vec_env_cls=SubprocVecEnv,
        vec_env_kwargs={"start_method": start_method},
    )


__all__ = [
    "ENVS",
    "EnvSnapshot",
    "EnvStateError",
    "SimulationConfig",
    "SoftRobotEnv",
    "env_ids",
    "get_state",
    "set_state",
    "make",
    "make_subproc_vec_env",
    "make_vector_env",
]
