"""Task checks of the environments beyond the API (tests/test_envs.py): experts and scripted
actions reach their goals, rewards follow their definitions, options do what they say."""

from __future__ import annotations

import pickle
import warnings

import gymnasium as gym
import numpy as np
import pytest

import pliant.envs  # noqa: F401  (registers the environments)
from pliant.envs import ENVS


def make(name: str, **kwargs) -> gym.Env:
    return gym.make(f"pliant/{name}-v0", **{**ENVS[name].quick, **kwargs})


@pytest.fixture(autouse=True)
def _quiet():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        yield


@pytest.mark.parametrize("kind", ["discrete", "continuous"])
def test_gripper_expert_lifts_the_cube_to_the_goal(kind):
    from pliant.envs.gripper import expert_action

    # The fingers need the default mesh to close on the cube (a coarse one locks).
    env = make("Gripper", action_type=kind, mesh_size=5.0)
    env.reset(seed=0, options={"cube": [2.0, -2.0], "goal": 12.0})
    for _ in range(40):
        *_, term, trunc, info = env.step(expert_action(env))
        if term or trunc:
            break
    assert term and info["is_success"]
    cube = env.unwrapped.cube()
    assert cube[2] > 9.0 and abs(cube[0] - 2.0) < 3.0


def test_gripper_push_down_pulls_the_cube_down_with_the_drawn_force():
    env = make("Gripper", cube_push_down=True, push_force=50.0)
    env.reset(seed=0)
    g = env.unwrapped
    g.state.rigid_positions[0, 2] += 5.0  # in the air: the first step's fall shows the push
    free = make("Gripper")
    free.reset(seed=0)
    free.unwrapped.state.rigid_positions[0, 2] += 5.0
    env.step(6)
    free.step(6)
    assert g.cube()[2] < free.unwrapped.cube()[2]


def _rollout(env, actions) -> list:
    return [env.step(a)[:2] for a in actions]


def test_space_debris_snapshot_carries_its_cube_size_and_replays_exactly():
    env = make("TrunkSpaceDebris")
    env.reset(seed=0, options={"cube_size": 20.0})
    still = -np.ones(8, dtype=np.float32)
    _, r, *_ = env.step(still)
    assert r == pytest.approx(-3.0, abs=1e-9)  # Eq. 3.3 at the start: each ratio is 1
    snapshot = pickle.dumps(pliant.envs.get_state(env))
    env.action_space.seed(3)
    actions = [env.action_space.sample() for _ in range(3)]
    first = _rollout(env, actions)
    env.reset(seed=1, options={"cube_size": 30.0})
    assert env.unwrapped.cube_size == 30.0
    pliant.envs.set_state(env, pickle.loads(snapshot))
    assert env.unwrapped.cube_size == 20.0
    again = _rollout(env, actions)
    other = make("TrunkSpaceDebris")  # a fresh environment builds the 20 mm model on restore
    other.reset(seed=5, options={"cube_size": 30.0})
    pliant.envs.set_state(other, pickle.loads(snapshot))
    there = _rollout(other, actions)
    for (o1, r1), (o2, r2), (o3, r3) in zip(first, again, there, strict=True):
        np.testing.assert_array_equal(o1, o2)
        np.testing.assert_array_equal(o1, o3)
        assert r1 == r2 == r3
