"""Environments as the learners see them: a picklable factory, a snapshot wrapper for exact
resume, and vectorised environments whose dead workers are restarted.

Worker processes start with "spawn" (numba's OpenMP kernels abort forked children, see
:mod:`pliant.envs`). A worker that dies (killed, out of memory, a crash in native code) shows
up in the parent as ``EOFError``/``BrokenPipeError``/``ConnectionResetError`` on its pipe:
:class:`RestartingSubprocVecEnv` starts a new one, resets its environment and reports the
interrupted episode as truncated (``info["worker_restarted"]``), so that training goes on.
"""

from __future__ import annotations

import copy
import multiprocessing as mp
import os
import warnings
from collections.abc import Callable
from functools import partial
from typing import Any

import gymnasium as gym
import numpy as np
from stable_baselines3.common.monitor import Monitor
from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecEnv
from stable_baselines3.common.vec_env.base_vec_env import CloudpickleWrapper
from stable_baselines3.common.vec_env.subproc_vec_env import _stack_obs, _worker

from pliant.processes import exit_with_parent

WORKER_ERRORS = (EOFError, BrokenPipeError, ConnectionResetError)


def register_envs() -> None:
    """Pliant's environments and the test environments (worker processes start without)."""
    import pliant.envs  # noqa: F401  (registers pliant/*-v0)
    from pliant.learn import toys

    toys.register()


class Resumable(gym.Wrapper):
    """Outermost wrapper: ``snapshot()``/``restore()`` of the whole stack (the environment's
    ``get_state``/``set_state``, a TimeLimit's step counter, the Monitor's running episode), so
    that a training run resumes mid-episode exactly. ``snapshot()`` is None for an environment
    without ``get_state``."""

    def snapshot(self) -> dict | None:
        base = self.env.unwrapped
        if not hasattr(base, "get_state"):
            return None
        layers = {}
        layer = self.env
        while isinstance(layer, gym.Wrapper):
            if isinstance(layer, gym.wrappers.TimeLimit):
                layers["time_limit"] = layer._elapsed_steps
            elif isinstance(layer, Monitor):
                layers["monitor"] = {
                    k: copy.deepcopy(getattr(layer, k))
                    for k in ("rewards", "needs_reset", "episode_returns", "episode_lengths")
                }
                layers["monitor"]["total_steps"] = layer.total_steps
            layer = layer.env
        return {"env": base.get_state(), "layers": layers}

    def restore(self, snapshot: dict) -> None:
        self.env.unwrapped.set_state(snapshot["env"])
        layers = snapshot["layers"]
        layer = self.env
        while isinstance(layer, gym.Wrapper):
            if isinstance(layer, gym.wrappers.TimeLimit):
                layer._elapsed_steps = layers["time_limit"]
            elif isinstance(layer, Monitor):
                for k, v in layers["monitor"].items():
                    setattr(layer, k, copy.deepcopy(v))
            elif isinstance(layer, gym.wrappers.OrderEnforcing):
                layer._has_reset = True  # restored mid-episode: stepping is allowed
            layer = layer.env


def make_env(
    env_id: str, env_kwargs: dict | None = None, render_mode: str | None = None
) -> gym.Env:
    """One environment as training uses it: ``gymnasium.make`` + Monitor + :class:`Resumable`.
    Picklable through ``functools.partial`` (the factory of worker processes)."""
    register_envs()
    kwargs = dict(env_kwargs or {})
    if render_mode is not None:
        kwargs["render_mode"] = render_mode
    # No passive checker: it insists on a reset before the first step, which a restored
    # snapshot makes unnecessary (the environments are checked by their own tests).
    return Resumable(Monitor(gym.make(env_id, disable_env_checker=True, **kwargs)))


def _orphan_safe(parent: int, factory: Callable[[], gym.Env]) -> gym.Env:
    """`factory`'s environment, in a worker that ends with its learner `parent`: a worker in
    the middle of a long step would otherwise notice its parent's death only at the next
    message (seconds to minutes for FEM environments)."""
    exit_with_parent(parent)
    return factory()


class RestartingSubprocVecEnv(SubprocVecEnv):
    """SubprocVecEnv that restarts a worker that died and goes on.

    The episode the dead worker was running ends there: the step returns done, the last
    observation that worker sent as ``terminal_observation``, ``TimeLimit.truncated`` (so that
    value-based learners bootstrap rather than treat it as a terminal state) and
    ``info["worker_restarted"] = True``; the new worker's environment is reset (unseeded).
    ``restarts`` counts them. Each worker ends within half a second of its learner's death.
    """

    def __init__(self, env_fns: list[Callable[[], gym.Env]], start_method: str = "spawn"):
        env_fns = [partial(_orphan_safe, os.getpid(), fn) for fn in env_fns]
        self._env_fns = env_fns
        self._ctx = mp.get_context(start_method)
        super().__init__(env_fns, start_method)
        self.remotes, self.work_remotes = list(self.remotes), list(self.work_remotes)
        self.restarts = 0
        self._last_obs: list[Any] = [None] * self.num_envs
        self._dead: set[int] = set()

    def _restart(self, i: int) -> tuple[Any, dict]:
        old = self.processes[i]
        if old.is_alive():
            old.terminate()
        old.join(timeout=5)
        self.remotes[i].close()
        remote, work_remote = self._ctx.Pipe()
        args = (work_remote, remote, CloudpickleWrapper(self._env_fns[i]))
        process = self._ctx.Process(target=_worker, args=args, daemon=True)
        process.start()
        work_remote.close()
        self.remotes[i], self.work_remotes[i], self.processes[i] = remote, work_remote, process
        self.restarts += 1
        warnings.warn(f"environment worker {i} died and was restarted", stacklevel=3)
        remote.send(("reset", (None, {})))
        return remote.recv()

    def step_async(self, actions: np.ndarray) -> None:
        for i, (remote, action) in enumerate(zip(self.remotes, actions, strict=True)):
            try:
                remote.send(("step", action))
            except WORKER_ERRORS:
                self._dead.add(i)
        self.waiting = True

    def _receive(self, restarted: Callable[[int], tuple]) -> list[tuple]:
        """Every worker's answer; `restarted(i)` stands for that of worker i, found dead (and
        restarted by it)."""
        results = []
        for i, remote in enumerate(self.remotes):
            try:
                if i in self._dead:
                    raise EOFError
                results.append(remote.recv())
            except WORKER_ERRORS:
                results.append(restarted(i))
        self._dead.clear()
        return results

    def _truncated(self, i: int) -> tuple:
        """The step of dead worker i: its episode ends, truncated, and a new one starts."""
        obs, reset_info = self._restart(i)
        last = self._last_obs[i] if self._last_obs[i] is not None else obs
        info = {"terminal_observation": last, "TimeLimit.truncated": True, "worker_restarted": True}
        return obs, 0.0, True, info, reset_info

    def step_wait(self):
        results = self._receive(self._truncated)
        self.waiting = False
        obs, rews, dones, infos, self.reset_infos = zip(*results, strict=True)
        self._last_obs = list(obs)
        return _stack_obs(obs, self.observation_space), np.stack(rews), np.stack(dones), infos

    def reset(self):
        for i in range(self.num_envs):
            try:
                self.remotes[i].send(("reset", (self._seeds[i], self._options[i])))
            except WORKER_ERRORS:
                self._dead.add(i)
        results = self._receive(self._restart)
        obs, self.reset_infos = zip(*results, strict=True)
        self._last_obs = list(obs)
        self._reset_seeds()
        self._reset_options()
        return _stack_obs(obs, self.observation_space)


def make_vec_env(
    env_id: str,
    n_envs: int = 1,
    *,
    env_kwargs: dict | None = None,
    backend: str = "subproc",
    ray_address: str | None = None,
    start_method: str = "spawn",
) -> VecEnv:
    """n_envs copies of an environment for training.

    backend: "subproc" (worker processes, restarted when they die), "dummy" (in this process;
    also what "subproc" gives for one environment, where a worker process costs more than it
    saves) or "ray" (Ray actors, :class:`pliant.learn.distributed.RayVecEnv`).
    """
    factories = [partial(make_env, env_id, env_kwargs) for _ in range(n_envs)]
    if backend == "ray":
        from pliant.learn.distributed import RayVecEnv

        return RayVecEnv(factories, address=ray_address)
    if backend == "subproc" and n_envs > 1:
        return RestartingSubprocVecEnv(factories, start_method=start_method)
    if backend in ("subproc", "dummy"):
        return DummyVecEnv(factories)
    raise ValueError(f"backend must be 'subproc', 'dummy' or 'ray', got {backend!r}")
