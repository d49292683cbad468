"""The proxy environments' task definitions (thesis §4.1.2, wave2_facts C.5) on hand-built
states: observation, action, reward and episode length."""

from __future__ import annotations

import dataclasses

import gymnasium as gym
import numpy as np
import pytest

import pliant.envs  # noqa: F401  (registers the environments)
from pliant.envs import ENVS
from pliant.envs.base import ActionError
from pliant.envs.multigait import FORWARD
from pliant.mesh.multigait import CHAMBERS


def _multigait(**kwargs):
    return gym.make("pliant/MultigaitProxy-v0", **{**ENVS["MultigaitProxy"].quick, **kwargs})


def test_multigait_proxy_episode_is_the_authors_timer() -> None:
    """12 steps of 0.6 s (SofaGym's timer 12, scale 60)."""
    env = gym.make("pliant/MultigaitProxy-v0")
    assert env.spec.max_episode_steps == 12
    assert env.unwrapped.substeps == 60 and env.unwrapped.step_time == pytest.approx(0.6)


def test_multigait_proxy_observation_with_commands() -> None:
    """``observe_commands``: the thesis' 20 points, then the chambers' commands in CHAMBERS
    order; action 2 (front pair inflated, all or nothing) sets the front chambers to 1 and
    leaves the others at 0."""
    plain, full = _multigait(), _multigait(observe_commands=True)
    assert full.observation_space.shape == (65,) and plain.observation_space.shape == (60,)
    a, _ = plain.reset(seed=0)
    b, _ = full.reset(seed=0)
    np.testing.assert_array_equal(b[:60], a)
    np.testing.assert_array_equal(b[60:], 0.0)
    a, *_ = plain.step(2)
    b, *_ = full.step(2)
    np.testing.assert_array_equal(b[:60], a)
    front = [c.startswith("front") for c in CHAMBERS]
    np.testing.assert_array_equal(b[60:], np.where(front, 1.0, 0.0))
    assert full.observation_space.contains(b)


def test_multigait_proxy_reward_is_the_forward_displacement() -> None:
    """Reward = x_t - x_{t-1} of the skeleton's centre of mass along forward (-x): a skeleton
    moved 5 mm forward by hand earns 5 mm; its observation moves by 5 / length."""
    env = _multigait().unwrapped
    obs, _ = env.reset(seed=0)
    n = env.proxy.rod.n_centreline
    shifted = env.state.positions.copy()
    shifted[:n] += 5.0 * FORWARD
    env.state = dataclasses.replace(env.state, positions=shifted)
    reward, terminated, parts = env._reward()
    assert reward == pytest.approx(5.0) and not terminated
    assert parts == {"forward": pytest.approx(5.0)}
    moved = env._observe().reshape(-1, 3) - obs.reshape(-1, 3)
    np.testing.assert_allclose(moved, np.tile(5.0 * FORWARD / env.length, (20, 1)), atol=1e-6)


def test_trunk_push_proxy_goal_is_drawn_in_x_and_z() -> None:
    """The goal is the cube's start plus an offset drawn in [goal_low, goal_high] on the floor
    (x, z), both coordinates varying; the observation ends with the cube's centre and the
    goal's (x, z), divided by the trunk's length."""
    env = gym.make("pliant/TrunkPushProxy-v0", **ENVS["TrunkPushProxy"].quick)
    base = env.unwrapped
    offsets = []
    for seed in range(8):
        obs, _ = env.reset(seed=seed)
        goal = base.task["goal"]
        offsets.append((goal - base.cube())[[0, 2]])
        assert goal[1] == pytest.approx(base.cube()[1])
        np.testing.assert_allclose(obs[-5:-2], base.cube() / base.length, rtol=1e-6)
        np.testing.assert_allclose(obs[-2:], goal[[0, 2]] / base.length, rtol=1e-6)
    offsets = np.array(offsets)
    assert np.all(offsets >= np.asarray(base.goal_low)) and np.all(offsets <= base.goal_high)
    assert np.ptp(offsets[:, 0]) > 5.0 and np.ptp(offsets[:, 1]) > 5.0


def test_trunk_push_proxy_reward_on_a_hand_placed_cube() -> None:
    """Reward = -d / L - w d_c / L, d the cube-goal distance in (x, z) (a height difference
    does not count), d_c the cube-to-nearest-node distance; solved under 8 mm."""
    env = gym.make("pliant/TrunkPushProxy-v0", **ENVS["TrunkPushProxy"].quick).unwrapped
    env.reset(seed=0, options={"goal": np.array([30.0, 0.0, 40.0])})
    for offset, solved in (((3.0, 7.0, 4.0), True), ((6.0, 0.0, 8.0), False)):
        cube = env.task["goal"] + np.array(offset)
        env.state = dataclasses.replace(env.state, rigid_positions=cube[None, :])
        reward, terminated, parts = env._reward()
        d = np.hypot(offset[0], offset[2])
        nodes = env.proxy.skeleton(env.state.positions)
        d_c = np.linalg.norm(nodes - cube, axis=1).min()
        L = env.length
        assert parts["goal"] == pytest.approx(-d / L)
        assert parts["contact"] == pytest.approx(-env.contact_weight * d_c / L)
        assert reward == pytest.approx(parts["goal"] + parts["contact"])
        assert terminated is solved


def test_trunk_push_proxy_bend_limit_scales_the_bending_actions() -> None:
    """An action of +-1 on a bending is a command of +-bend_limit (the thesis' a priori
    amplitude limit); the base's action keeps its range."""
    env = gym.make(
        "pliant/TrunkPushProxy-v0", **{**ENVS["TrunkPushProxy"].quick, "bend_limit": 0.2}
    ).unwrapped
    env.reset(seed=0)
    env.step(np.array([1.0, -1.0, 0.5, 0.0, 0.0]))
    np.testing.assert_allclose(env.commands[:4], [0.2, -0.2, 0.1, 0.0])
    with pytest.raises(ValueError, match="bend_limit"):
        gym.make("pliant/TrunkPushProxy-v0", bend_limit=0.0)


def test_a_planar_trunk_push_proxy_bends_its_beams_towards_x_only() -> None:
    """planar: Box(3) actions drive the two bendings towards +-x (lower_d2, upper_d2) and the
    base, the bendings towards +-y stay 0, and the bent trunk stays in the floor's plane
    (its tip's height is the unbent trunk's); Discrete(6) steps the same three."""
    kwargs = {**ENVS["TrunkPushProxy"].quick, "bend_limit": 0.2}
    env = gym.make("pliant/TrunkPushProxy-v0", planar=True, **kwargs).unwrapped
    assert env.action_space.shape == (3,)
    env.reset(seed=0)
    still = env.proxy.skeleton(env.state.positions)[-1]
    env.step(np.array([1.0, -0.5, 0.0]))
    np.testing.assert_allclose(env.commands[:4], [0.0, 0.2, 0.0, -0.1])
    tip = env.proxy.skeleton(env.state.positions)[-1]
    assert abs(tip[0] - still[0]) > 5.0  # bent sideways along x...
    assert abs(tip[1] - still[1]) < 0.1 * abs(tip[0] - still[0])  # ...not up or down
    with pytest.raises(ActionError, match="shape"):
        env.step(np.zeros(5))
    discrete = gym.make(
        "pliant/TrunkPushProxy-v0", planar=True, action_type="discrete", **kwargs
    ).unwrapped
    assert discrete.action_space.n == 6
    discrete.reset(seed=0)
    discrete.step(2)  # the upper beam towards +x
    discrete.step(5)  # the base back
    np.testing.assert_allclose(discrete.commands[:4], [0.0, 0.0, 0.0, 0.2])
    assert discrete.commands[4] == pytest.approx(-discrete.base_step)


def test_the_trunk_push_proxy_takes_the_fem_trunks_cable_actions() -> None:
    """actions="cables": Box(9) as the FEM TrunkPush's (absolute cable targets within
    bend_limit of the courses, then the base), mapped by the calibration's cables -> bendings
    map; two opposite cables pulled alike cancel."""
    from pliant.proxy.references import trunk_commands

    kwargs = {**ENVS["TrunkPushProxy"].quick, "bend_limit": 0.2}
    env = gym.make("pliant/TrunkPushProxy-v0", actions="cables", **kwargs).unwrapped
    assert env.action_space.shape == (9,)
    env.reset(seed=0)
    action = -np.ones(9)
    action[3], action[8] = 1.0, 0.0  # the long +x cable to 14 mm, the base still
    env.step(action)
    np.testing.assert_allclose(env.commands[:4], [0.0, 0.1, 0.0, 0.2])
    np.testing.assert_allclose(env.commands[:4], trunk_commands([0, 0, 0, 14, 0, 0, 0, 0])[:4])
    action[1] = 1.0  # the long -x cable as far: no bending left
    env.step(action)
    np.testing.assert_allclose(env.commands[:4], 0.0, atol=1e-12)
    with pytest.raises(ValueError, match="cables"):
        gym.make("pliant/TrunkPushProxy-v0", actions="cables", action_type="discrete")
