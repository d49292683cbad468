"""Copies of an environment stepped on threads of one process (a Gymnasium VectorEnv).

:class:`ThreadedVectorEnv` is Gymnasium's ``SyncVectorEnv`` whose copies take their step (and
the reset that ends an episode) at the same time, one thread each: the scheme of
:class:`pliant.solvers.BatchedImplicitEuler` at the level of the environment step. What runs
in parallel is what releases the GIL (the compiled kernels, CHOLMOD's factorisations and
solves); the step's Python runs one copy at a time. Two copies on two threads stepped faster
than two spawned worker processes (:func:`pliant.envs.make_subproc_vec_env`) on the Diamond,
whose step is mostly compiled work, and on the SimpleMaze, whose step is mostly Python
(collision and contact rows): no pickling of actions and observations, no second process
competing for the cores (docs/concepts/speed.md, "Environments (#62 item 3)").

Each copy's step is its own: the results are those of ``SyncVectorEnv`` bit for bit, whatever
the threads do. A copy factorises on its own thread (``ImplicitEuler``'s background
factorisation thread is one for the whole process, on which the copies would queue).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from copy import deepcopy

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode, SyncVectorEnv
from gymnasium.vector.utils import concatenate, iterate


class ThreadedVectorEnv(SyncVectorEnv):
    """``SyncVectorEnv`` (same arguments) whose copies step at the same time on `threads`
    threads (default: the machine's cores, at most the copies)."""

    def __init__(
        self, env_fns: Sequence[Callable[[], gym.Env]], *, threads: int | None = None, **kwargs
    ) -> None:
        super().__init__(env_fns, **kwargs)
        if threads is None:
            threads = min(len(self.envs), os.cpu_count() or 1)
        if isinstance(threads, bool) or not isinstance(threads, int) or threads < 1:
            raise ValueError(f"threads must be an integer >= 1, got {threads!r}")
        self.threads = threads
        self._pool = ThreadPoolExecutor(threads, thread_name_prefix="pliant-env")
        for env in self.envs:
            sim = getattr(env.unwrapped, "sim", None)
            if sim is not None and hasattr(sim, "_background"):
                sim._background = False  # (module docstring): the copies are the concurrency

    def _one(self, i: int, action) -> tuple:
        """Copy i's step (or the reset that ends its episode): (obs, reward, terminated,
        truncated, info, (final obs, final info) or None)."""
        env = self.envs[i]
        if self.autoreset_mode == AutoresetMode.NEXT_STEP and self._autoreset_envs[i]:
            obs, info = env.reset()
            return obs, 0.0, False, False, info, None
        if self.autoreset_mode == AutoresetMode.DISABLED:
            assert not self._autoreset_envs[i], f"{self._autoreset_envs=}"
        obs, reward, terminated, truncated, info = env.step(action)
        final = None
        if self.autoreset_mode == AutoresetMode.SAME_STEP and (terminated or truncated):
            final = (obs, info)
            obs, info = env.reset()
        return obs, reward, terminated, truncated, info, final

    def step(self, actions):
        """``SyncVectorEnv.step`` with the copies' steps on the threads."""
        actions = list(iterate(self.action_space, actions))
        if len(actions) != len(self.envs):
            raise ValueError(f"{len(actions)} actions for {len(self.envs)} environments")
        results = list(self._pool.map(self._one, range(len(self.envs)), actions))
        infos: dict = {}
        for i, (obs, reward, terminated, truncated, info, final) in enumerate(results):
            self._env_obs[i] = obs
            self._rewards[i] = reward
            self._terminations[i] = terminated
            self._truncations[i] = truncated
            if final is not None:
                infos = self._add_info(infos, {"final_obs": final[0], "final_info": final[1]}, i)
            infos = self._add_info(infos, info, i)
        self._observations = concatenate(
            self.single_observation_space, self._env_obs, self._observations
        )
        self._autoreset_envs = np.logical_or(self._terminations, self._truncations)
        return (
            deepcopy(self._observations) if self.copy else self._observations,
            np.copy(self._rewards),
            np.copy(self._terminations),
            np.copy(self._truncations),
            infos,
        )

    def close_extras(self, **kwargs) -> None:
        self._pool.shutdown()
        super().close_extras(**kwargs)
