"""Property tests (Hypothesis) of the environment API, for every registered id (quick
variants, built as `tests/envs/test_snapshots.py` builds them): for any seed, action sequence
and restore point,

- every observation is finite, inside the observation space and not a view of the previous one;
- every reward is finite and equals the sum of ``info["reward_parts"]``;
- a reset with the same seed after the episode gives the same first observation;
- the step from a snapshot taken at the restore point (pickled, then restored after the rest of
  the episode) equals the original step bit for bit: observation, reward, flags, reward parts.

Each environment is built once for the module and reused by every example (building is the
expensive part). Examples are derandomised, so CI draws the same ones on every run;
``HYPOTHESIS_PROFILE=nightly`` draws more. `test_an_injected_fault_is_found` shows the
properties can fail: a NaN in one observation, a snapshot that forgets the commands, reward parts
that do not add up, each injected into a live environment, are found.
"""

from __future__ import annotations

import dataclasses
import os
import pickle
import warnings
from functools import cache

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import strategies as st
from test_snapshots import IDS, make

import pliant.envs as envs

#: Examples per environment: the CI run of the whole file stays under a minute on two cores.
EXAMPLES = {"ci": 5, "nightly": 100}[os.environ.get("HYPOTHESIS_PROFILE", "ci")]
#: Steps of an example's action sequence, at most.
STEPS = 5

PROPERTY_SETTINGS = settings(
    max_examples=EXAMPLES,
    deadline=None,
    derandomize=True,
    database=None,
    suppress_health_check=[HealthCheck.too_slow],
)


@cache
def quick_env(name: str) -> gym.Env:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return make(name)


def actions(space: gym.Space) -> st.SearchStrategy:
    """Any valid action of the space: an integer of a discrete space, a float32 vector of a box
    (each coordinate within its bounds)."""
    if isinstance(space, gym.spaces.Discrete):
        return st.integers(int(space.start), int(space.start + space.n - 1))
    bounds = zip(space.low.ravel(), space.high.ravel(), strict=True)
    coordinates = [st.floats(float(lo), float(hi), width=32) for lo, hi in bounds]
    return st.tuples(*coordinates).map(lambda a: np.array(a, np.float32).reshape(space.shape))


def _assert_sound(env: gym.Env, step: tuple, previous: np.ndarray) -> None:
    obs, reward, terminated, truncated, info = step
    assert np.all(np.isfinite(obs)), f"non-finite observation {obs}"
    assert env.observation_space.contains(obs), f"observation outside the space: {obs}"
    assert not np.shares_memory(obs, previous), "an observation shares memory with the last one"
    assert isinstance(reward, float) and np.isfinite(reward), f"reward {reward!r}"
    assert isinstance(terminated, bool) and isinstance(truncated, bool)
    parts = info.get("reward_parts")
    if parts is not None:
        assert all(np.isfinite(v) for v in parts.values()), f"reward parts {parts}"
        total = sum(parts.values())
        assert total == pytest.approx(reward, rel=1e-12, abs=1e-12), (
            f"reward parts {parts} do not add up to the reward {reward}: {total}"
        )


def _assert_same_step(first: tuple, second: tuple) -> None:
    (o1, r1, t1, u1, i1), (o2, r2, t2, u2, i2) = first, second
    np.testing.assert_array_equal(o1, o2, err_msg="the restored step's observation differs")
    assert (r1, t1, u1) == (r2, t2, u2), "the restored step's reward or flags differ"
    assert i1.get("reward_parts") == i2.get("reward_parts"), "the restored reward parts differ"
    assert i1.get("diverged") == i2.get("diverged")


def check_episode(env: gym.Env, seed: int, sequence: list, restore_at: int) -> None:
    """The properties of the module docstring on one episode."""
    first, _ = env.reset(seed=seed)
    assert np.all(np.isfinite(first)) and env.observation_space.contains(first)
    previous, steps, snapshot = first, [], None
    for k, action in enumerate(sequence):
        if k == restore_at:
            snapshot = pickle.dumps(envs.get_state(env))
        step = env.step(action)
        _assert_sound(env, step, previous)
        steps.append(step)
        previous = step[0]
        if step[2] or step[3]:
            break
    if snapshot is not None:
        envs.set_state(env, pickle.loads(snapshot))
        _assert_same_step(steps[restore_at], env.step(sequence[restore_at]))
    again, _ = env.reset(seed=seed)
    np.testing.assert_array_equal(first, again, err_msg="a seeded reset depends on the history")


@st.composite
def episodes(draw, name: str) -> tuple[int, list, int]:
    """(seed, action sequence, restore point within it) for one environment."""
    space = quick_env(name).action_space
    seed = draw(st.integers(0, 2**31 - 1))
    sequence = draw(st.lists(actions(space), min_size=2, max_size=STEPS))
    return seed, sequence, draw(st.integers(0, len(sequence) - 1))


@pytest.mark.parametrize("name", IDS)
def test_random_episodes_are_sound_and_restore_exactly(name):
    env = quick_env(name)

    @PROPERTY_SETTINGS
    @given(episodes(name))
    def prop(episode):
        seed, sequence, restore_at = episode
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            check_episode(env, seed, sequence, restore_at)

    prop()


def _nan_in_the_second_observation(monkeypatch, env: gym.Env) -> None:
    inner, clip = env.unwrapped, env.unwrapped._clip_observation

    def faulty(obs):
        out = clip(obs)
        if inner._elapsed == 2:
            out = out.copy()
            out[0] = np.nan
        return out

    monkeypatch.setattr(inner, "_clip_observation", faulty)


def _snapshot_without_commands(monkeypatch, env: gym.Env) -> None:
    inner, get_state = env.unwrapped, env.unwrapped.get_state

    def faulty():
        snapshot = get_state()
        return dataclasses.replace(snapshot, commands=np.zeros_like(snapshot.commands))

    monkeypatch.setattr(inner, "get_state", faulty)


def _reward_parts_off(monkeypatch, env: gym.Env) -> None:
    inner, reward = env.unwrapped, env.unwrapped._reward

    def faulty():
        value, terminated, parts = reward()
        if inner._elapsed == 3:
            parts = {**parts, "bonus": 1e-6}
        return value, terminated, parts

    monkeypatch.setattr(inner, "_reward", faulty)


@pytest.mark.parametrize(
    ("fault", "found"),
    [
        (_nan_in_the_second_observation, "non-finite observation"),
        (_snapshot_without_commands, "the restored step's observation differs"),
        (_reward_parts_off, "do not add up"),
    ],
)
def test_an_injected_fault_is_found(monkeypatch, fault, found):
    """Each fault shows only in some episodes (two or three steps long, or restored after a
    command); the property must find one of them."""
    name = "Diamond"
    env = quick_env(name)
    fault(monkeypatch, env)

    @settings(
        PROPERTY_SETTINGS, max_examples=30, phases=[Phase.generate], report_multiple_bugs=False
    )
    @given(episodes(name))
    def prop(episode):
        check_episode(env, *episode)

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with pytest.raises(AssertionError, match=found):
            prop()
