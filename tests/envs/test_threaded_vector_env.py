"""ThreadedVectorEnv (pliant.envs.vector): copies stepped on threads give SyncVectorEnv's
results bit for bit, across an episode's end (the next step resets that copy)."""

from __future__ import annotations

from functools import partial

import gymnasium as gym
import numpy as np
import pytest

from pliant import envs
from pliant.envs import ENVS, ThreadedVectorEnv


def _run(vec, steps: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    vec.action_space.seed(0)
    obs, _ = vec.reset(seed=[3, 4])
    observations, rewards, ends = [obs], [], []
    for _ in range(steps):
        obs, reward, terminated, truncated, _ = vec.step(vec.action_space.sample())
        observations.append(obs)
        rewards.append(reward)
        ends.append(terminated | truncated)
    vec.close()
    return np.array(observations), np.array(rewards), np.array(ends)


def test_threads_give_the_sequential_results():
    factory = partial(
        envs.make, "pliant/CartStem-v0", max_episode_steps=2, **ENVS["CartStem"].quick
    )
    threaded = ThreadedVectorEnv([factory, factory])
    assert threaded.threads >= 1
    assert all(not e.unwrapped.sim._background for e in threaded.envs)
    got = _run(threaded, 5)
    expected = _run(gym.vector.SyncVectorEnv([factory, factory]), 5)
    assert got[2].any()  # an episode ended within the run (then the copy is reset)
    for a, b in zip(got, expected, strict=True):
        np.testing.assert_array_equal(a, b)


def test_factory_and_bad_threads():
    vec = envs.make_threaded_vec_env("pliant/CartStem-v0", 2, threads=2, **ENVS["CartStem"].quick)
    assert vec.num_envs == 2 and vec.threads == 2
    vec.close()
    with pytest.raises(ValueError, match="threads"):
        ThreadedVectorEnv([partial(envs.make, "pliant/CartStem-v0")], threads=0)
