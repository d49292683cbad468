"""Exact snapshots of every registered environment (quick variants): a step from a restored
``get_state()`` equals the original step bit for bit after Gymnasium's ``check_env`` ran on the
environment, after a random-action episode, and in a fresh process fed the pickled snapshot
(one spawned process for all ids: numba's OpenMP forbids fork)."""

from __future__ import annotations

import multiprocessing as mp
import pickle
import warnings
from functools import cache

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import pliant.envs as envs
from pliant.envs import ENVS

IDS = sorted(ENVS)
#: Steps of the random-action history, at most (a whole episode where one is shorter).
EPISODE = 12


def make(name: str) -> gym.Env:
    return gym.make(f"pliant/{name}-v0", **ENVS[name].quick)


def _steps(env: gym.Env, actions) -> list:
    out = []
    for a in actions:
        obs, reward, terminated, truncated, _ = env.step(a)
        out.append((obs, reward, terminated, truncated))
        if terminated or truncated:
            break
    return out


def _assert_same(first: list, second: list) -> None:
    assert len(first) == len(second)
    for (o1, r1, *e1), (o2, r2, *e2) in zip(first, second, strict=True):
        np.testing.assert_array_equal(o1, o2)
        assert r1 == r2 and e1 == e2


@cache
def _reference(name: str) -> tuple[gym.Env, bytes, list, list]:
    """An environment two random steps into an episode, its pickled snapshot, two actions and
    the steps they gave from there."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        env = make(name)
        env.reset(seed=1)
        env.action_space.seed(1)
        _steps(env, [env.action_space.sample() for _ in range(2)])
        blob = pickle.dumps(envs.get_state(env))
        actions = [env.action_space.sample() for _ in range(2)]
        return env, blob, actions, _steps(env, actions)


def _replay(env: gym.Env, blob: bytes, actions: list) -> list:
    envs.set_state(env, pickle.loads(blob))
    return _steps(env, actions)


@pytest.mark.parametrize("name", IDS)
def test_restore_is_exact_after_check_env_and_an_episode(name):
    env, blob, actions, first = _reference(name)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        check_env(env.unwrapped, skip_render_check=True)
        _assert_same(first, _replay(env, blob, actions))
        env.reset(seed=5)
        env.action_space.seed(5)
        n = min(EPISODE, ENVS[name].max_episode_steps)
        _steps(env, [env.action_space.sample() for _ in range(n)])
        _assert_same(first, _replay(env, blob, actions))


def _replay_fresh(cases: list[tuple[str, bytes, list]]) -> list[list]:
    """In a spawned process: each snapshot restored into a newly made environment."""
    warnings.simplefilter("ignore")
    out = []
    for name, blob, actions in cases:
        env = make(name)
        env.reset(seed=0)
        out.append(_replay(env, blob, actions))
    return out


def test_restore_is_exact_in_a_fresh_process():
    references = {n: _reference(n) for n in IDS}
    cases = [(n, blob, actions) for n, (_, blob, actions, _) in references.items()]
    with mp.get_context("spawn").Pool(1) as pool:
        there = pool.apply(_replay_fresh, (cases,))
    for name, steps in zip(IDS, there, strict=True):
        _assert_same(references[name][3], steps)


def test_every_registered_id_is_covered():
    """The snapshot and property tests run over ``ENVS``: an id registered without an entry
    there (no quick variant) would escape them."""
    registered = {name for name in gym.registry if name.startswith("pliant/")}
    assert registered == {f"pliant/{name}-v0" for name in IDS}
