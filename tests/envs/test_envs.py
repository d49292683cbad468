"""The environment suite: Gymnasium and SB3 API checks, seeding, observations in their space,
reward parts, exact save/restore (also through pickle into another process), bad input,
divergence, vectorised stepping with spawned workers."""

from __future__ import annotations

import multiprocessing as mp
import pickle
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env as gym_check_env
from stable_baselines3.common.env_checker import check_env as sb3_check_env

import pliant.envs as envs
from pliant.envs import ENVS, EnvStateError
from pliant.errors import DivergenceError

IDS = sorted(ENVS)


def make(name: str, **kwargs) -> gym.Env:
    return gym.make(f"pliant/{name}-v0", **{**ENVS[name].quick, **kwargs})


@pytest.fixture(autouse=True)
def _quiet():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        yield


def _actions(env: gym.Env, n: int, seed: int) -> list:
    env.action_space.seed(seed)
    return [env.action_space.sample() for _ in range(n)]


def _rollout(env: gym.Env, actions) -> list:
    out = []
    for a in actions:
        obs, r, term, trunc, info = env.step(a)
        out.append((obs, r, term, trunc))
        if term or trunc:
            break
    return out


@pytest.mark.parametrize("name", IDS)
def test_api_checks_seeding_and_rollout(name):
    env = make(name)
    gym_check_env(env.unwrapped, skip_render_check=True)
    sb3_check_env(env.unwrapped, warn=False)
    a, _ = env.reset(seed=3)
    b, _ = env.reset(seed=3)
    np.testing.assert_array_equal(a, b)
    assert a.dtype == np.float32 and env.observation_space.contains(a)
    for action in _actions(env, 3, seed=0):
        obs, r, term, trunc, info = env.step(action)
        assert np.all(np.isfinite(obs)) and np.isfinite(r)
        assert env.observation_space.contains(obs)
        assert "diverged" not in info
        assert sum(info["reward_parts"].values()) == pytest.approx(r, abs=1e-12)
        if term or trunc:
            break


@pytest.mark.parametrize("name", IDS)
def test_continuous_and_discrete_variants(name):
    for kind in ("discrete", "continuous"):
        env = make(name, action_type=kind)
        env.reset(seed=0)
        expected = gym.spaces.Discrete if kind == "discrete" else gym.spaces.Box
        assert isinstance(env.action_space, expected)
        obs, *_ = env.step(env.action_space.sample())
        assert env.observation_space.contains(obs)


def _replay(snapshot_bytes: bytes, name: str, actions: list) -> list:
    env = make(name)
    env.reset(seed=0)
    envs.set_state(env, pickle.loads(snapshot_bytes))
    return _rollout(env, actions)


@pytest.mark.parametrize("name", IDS)
def test_restore_replays_bit_exactly(name):
    env = make(name)
    env.reset(seed=1)
    _rollout(env, _actions(env, 2, seed=1))  # a history the restore must not depend on
    snap = env.unwrapped.get_state()
    actions = _actions(env, 3, seed=2)
    first = _rollout(env, actions)
    _rollout(env, _actions(env, 2, seed=5))  # another history
    envs.set_state(env, pickle.loads(pickle.dumps(snap)))
    second = _rollout(env, actions)
    assert len(first) == len(second)
    for (o1, r1, *e1), (o2, r2, *e2) in zip(first, second, strict=True):
        np.testing.assert_array_equal(o1, o2)
        assert r1 == r2 and e1 == e2


def test_restore_in_another_process_is_bit_exact():
    name = "CartStemContact"
    env = make(name)
    env.reset(seed=4)
    _rollout(env, _actions(env, 2, seed=4))
    blob = pickle.dumps(env.unwrapped.get_state())
    actions = _actions(env, 3, seed=7)
    here = _rollout(env, actions)
    with mp.get_context("spawn").Pool(1) as pool:
        there = pool.apply(_replay, (blob, name, actions))
    for (o1, r1, *_), (o2, r2, *_) in zip(here, there, strict=True):
        np.testing.assert_array_equal(o1, o2)
        assert r1 == r2


def test_snapshot_of_another_environment_or_model_is_refused():
    diamond = make("Diamond")
    diamond.reset(seed=0)
    trunk = make("Trunk")
    trunk.reset(seed=0)
    with pytest.raises(EnvStateError, match="Trunk"):
        diamond.unwrapped.set_state(trunk.unwrapped.get_state())
    finer = make("Diamond", mesh_size=16.0)
    finer.reset(seed=0)
    with pytest.raises(EnvStateError, match="nodes"):
        diamond.unwrapped.set_state(finer.unwrapped.get_state())
    with pytest.raises(EnvStateError):
        diamond.unwrapped.set_state({"positions": 0})


def test_bad_actions_raise_and_continuous_values_are_clipped():
    env = make("Diamond")
    env.reset(seed=0)
    for bad in (8, -1, 1.5, "a", np.array([1, 2])):
        with pytest.raises(gym.error.InvalidAction):
            env.step(bad)
    env = make("Diamond", action_type="continuous")
    env.reset(seed=0)
    for bad in (np.zeros(3), np.array([np.nan, 0, 0, 0]), np.array(["a"] * 4)):
        with pytest.raises(gym.error.InvalidAction):
            env.step(bad)
    env.step(np.full(4, 7.0))  # clipped to 1: every cable at its maximum
    np.testing.assert_allclose(env.unwrapped.commands, env.unwrapped.max_commands)


def test_divergence_truncates_with_the_last_finite_observation(monkeypatch):
    env = make("Diamond")
    obs0, _ = env.reset(seed=0)

    def diverge(state, control=None):
        raise DivergenceError("blown up", step=state.step, cause="energy")

    monkeypatch.setattr(env.unwrapped.sim, "step", diverge)
    obs, r, term, trunc, info = env.step(0)
    np.testing.assert_array_equal(obs, obs0)
    # Eq. 3.2 where the step began: no progress.
    assert trunc and not term and r == 0.0 and "blown up" in info["diverged"]


def test_a_diverged_step_is_rewarded_as_staying_where_it_began(monkeypatch):
    # CartStemContact's reward is -|x_tip - x_goal| / L: a reward of 0 would pay the agent for
    # breaking the simulation; it gets the reward of the state the step began in.
    env = make("CartStemContact")
    obs0, _ = env.reset(seed=0)
    base = env.unwrapped
    start = base.state
    expected = -abs(base.tip_x() - base.task["goal"]) / base.length

    def diverge(state, control=None):
        raise DivergenceError("blown up", step=state.step, cause="energy")

    monkeypatch.setattr(base.sim, "step", diverge)
    obs, r, term, trunc, info = env.step(np.array([1.0], dtype=np.float32))
    np.testing.assert_array_equal(obs, obs0)
    assert trunc and not term and "blown up" in info["diverged"]
    assert expected < 0.0 and r == pytest.approx(expected)
    assert base.state is start


def test_rewards_of_the_thesis_and_sofagym_variants():
    # Eq. 3.2 on the Diamond: pulling a cable moves the top away from its elbow; towards a goal
    # on that side each step is rewarded with the relative decrease of the distance, in [0, 1].
    env = make("Diamond", goal_tolerance=0.1)
    env.reset(seed=0, options={"goal": [10.0, 0.0, 120.0]})
    d0 = env.unwrapped.distance()
    rewards = []
    for _ in range(4):
        _, r, *_ = env.step(2)  # pull cable 1 (its elbow at x = -97)
        rewards.append(r)
    assert all(0.0 <= r <= 1.0 for r in rewards)
    assert env.unwrapped.distance() < d0 and max(rewards) > 0
    mg = make("Multigait", reward="sofagym")
    mg.reset(seed=0)
    for a in (4, 0, 2, 5):
        _, r, *_ = mg.step(a)
        assert r >= 0.0


def test_maze_geodesic_distance_follows_the_corridors():
    env = make("SimpleMaze")
    env.reset(seed=0, options={"goal": 3})
    maze = env.unwrapped
    start, goal = maze.corners[0], maze.corners[3]
    straight = float(np.linalg.norm(goal - start))
    geodesic = maze.geodesic.at(maze._fields[3], np.array([*start, 0.0]))
    # Three corridors of length ~2 * 19.3 joined at their ends: at least 3 straight lengths.
    assert geodesic > 2.5 * straight / np.sqrt(2)
    assert maze.geodesic.at(maze._fields[3], np.array([*goal, 0.0])) < 1.0


@pytest.mark.parametrize("name", ["Multigait", "CartStemContact"])
def test_async_vector_env_with_spawned_workers(name):
    vec = envs.make_vector_env(f"pliant/{name}-v0", 2, **ENVS[name].quick)
    try:
        obs, _ = vec.reset(seed=0)
        assert obs.shape[0] == 2
        vec.action_space.seed(0)
        obs, r, term, trunc, info = vec.step(vec.action_space.sample())
        assert np.all(np.isfinite(obs)) and np.all(np.isfinite(r))
    finally:
        vec.close()


def test_sb3_subproc_vec_env():
    vec = envs.make_subproc_vec_env("pliant/Diamond-v0", 2, seed=0, **ENVS["Diamond"].quick)
    try:
        obs = vec.reset()
        obs, r, done, info = vec.step(np.array([0, 1]))
        assert obs.shape == (2, 18) and np.all(np.isfinite(r))
    finally:
        vec.close()


def test_rgb_render():
    env = make("Diamond", render_mode="rgb_array")
    env.reset(seed=0)
    frame = env.render()
    assert frame.ndim == 3 and frame.shape[2] == 3 and frame.dtype == np.uint8
    assert frame.min() < 200  # something is drawn on the white background
