"""Task checks of the environments beyond the API (tests/envs/test_envs.py): experts and scripted
actions reach their goals, rewards follow their definitions, options do what they say."""

from __future__ import annotations

import pickle
import re
import warnings
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import pliant.envs  # noqa: F401  (registers the environments)
from pliant.envs import ENVS, EnvStateError


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


def test_trunk_cup_curling_over_the_cup_drags_it_to_a_goal_behind():
    env = make("TrunkCup", action_type="continuous")
    env.reset(seed=0)
    cup = env.unwrapped.cup().copy()
    env.reset(seed=0, options={"goal": cup + [0.0, 0.0, -25.0]})
    curl = -np.ones(8, dtype=np.float32)
    curl[2] = 2 * 25.0 / 70.0 - 1  # the -y cable (CURL_DOWN_CABLE) to 25 mm
    rewards = [env.step(curl)[1] for _ in range(8)]
    assert env.unwrapped.cup()[2] < cup[2] - 10.0
    assert sum(rewards) > 0.3 and min(rewards) >= 0.0


def test_trunk_push_bending_onto_the_cube_pushes_it_along_x():
    env = make("TrunkPush")
    env.reset(seed=0)
    start = env.unwrapped.cube().copy()
    bend = -np.ones(9, dtype=np.float32)
    bend[3] = 2 * 15.0 / 70.0 - 1  # the +x cable to 15 mm
    bend[8] = 0.0  # the carriage at the middle of its course (0 mm)
    for _ in range(6):
        *_, info = env.step(bend)
    assert env.unwrapped.cube()[0] > start[0] + 5.0
    assert set(info["reward_parts"]) == {"goal", "contact"}


def test_a_planar_trunk_push_drives_the_x_cables_alone_and_pushes_as_the_full_one():
    """planar: Box(5) drives the -x/+x cables (1, 3, 5, 7) and the carriage, the others stay
    slack; the same +x pull as above moves the cube as the full action space does."""
    full, planar = make("TrunkPush"), make("TrunkPush", planar=True)
    assert planar.action_space.shape == (5,)
    for env in (full, planar):
        env.reset(seed=0)
    action = -np.ones(9, dtype=np.float32)
    action[3], action[8] = 2 * 15.0 / 70.0 - 1, 0.0
    for _ in range(3):
        full.step(action)
        planar.step(action[[1, 3, 5, 7, 8]])
    cables = planar.unwrapped.commands
    np.testing.assert_allclose(cables[[0, 2, 4, 5, 6, 7]], 0.0)
    np.testing.assert_allclose(cables, full.unwrapped.commands)
    np.testing.assert_allclose(planar.unwrapped.cube(), full.unwrapped.cube(), atol=1e-9)
    discrete = make("TrunkPush", planar=True, action_type="discrete")
    assert discrete.action_space.n == 10
    discrete.reset(seed=0)
    discrete.step(2)  # cable 3 (the long +x one) pulled...
    assert discrete.unwrapped.commands[3] > 0.0
    discrete.step(3)  # ...and released again
    discrete.step(4)  # cable 5 pulled
    np.testing.assert_allclose(np.flatnonzero(discrete.unwrapped.commands), [5])


def test_rod_manipulator_opposite_bendings_turn_the_rod():
    from pliant.robots.rod_manipulator import demo_actuation

    env = make("RodManipulator")
    env.reset(seed=0, options={"goal": np.radians(90.0)})
    rewards = []
    for k in range(8):
        cables = demo_actuation(0.15 + 0.1 * k) / 15.0 * 2.0 - 1.0
        base = (-7.0 + 10.0) / 15.0 * 2.0 - 1.0  # pressed 2 mm on the rod
        _, r, *_ = env.step(np.append(cables, base).astype(np.float32))
        rewards.append(r)
    assert np.degrees(env.unwrapped.task["angle"]) > 10.0
    assert rewards[-1] > rewards[0] and rewards[0] == pytest.approx(-1.0, abs=0.05)


@pytest.mark.parametrize(("cart", "caught"), [(1.0, True), (-1.0, False)])
def test_catch_the_object_under_the_ball_catches_it(cart, caught):
    env = make("CatchTheObject")
    env.reset(seed=0, options={"ball_x": 25.0})
    for _ in range(30):
        *_, term, trunc, info = env.step(np.array([cart * 25.0 / 40.0], dtype=np.float32))
        if term or trunc:
            break
    assert info["is_success"] == caught
    assert term != caught  # a missed ball ends the episode


def test_stem_pendulum_pumping_raises_the_tip():
    env = make("StemPendulum", substeps=10)
    env.reset(seed=0)
    _, r0, *_ = env.step(np.zeros(1, dtype=np.float32))
    assert r0 == pytest.approx(-1.0, abs=1e-4)  # hanging still: dist = 2 L (stretched 1 um)
    best = r0
    for _ in range(20):
        # Push with the swing: a positive torque (about +y) moves the hanging tip towards -x.
        obs = env.unwrapped._last_obs
        push = -1.0 if obs[2] >= 0 else 1.0
        _, r, *_ = env.step(np.array([push], dtype=np.float32))
        best = max(best, r)
    assert best > -0.6  # the tip above the pivot's level: dist < 1.2 L


def test_cart_stem_ends_when_the_cart_runs_away():
    env = make("CartStem")
    env.reset(seed=0, options={"speed": 0.0})
    steps = 0
    for _ in range(80):
        *_, term, trunc, info = env.step(0)
        steps += 1
        if term or trunc:
            break
    assert term and steps < 20


def test_cart_stem_contact_starts_at_rest_on_a_random_cart_between_the_obstacles():
    env = make("CartStemContact")
    carts = []
    for seed in range(6):
        obs, _ = env.reset(seed=seed)
        carts.append(env.unwrapped.cart_x())
        assert obs[0] == pytest.approx(obs[1], abs=1e-6)  # cart and tip on one vertical
    assert max(np.abs(carts)) <= 10.0 and np.ptp(carts) > 5.0
    env.reset(options={"cart": 7.0, "goal": -20.0})
    for _ in range(3):  # holding the cart where it starts leaves the beam still
        obs, *_ = env.step(np.array([7.0 / 40.0]))
    assert obs[1] * 100.0 == pytest.approx(7.0, abs=0.01)
    with pytest.raises(ValueError, match="cart_range"):
        make("CartStemContact", cart_range=15.0)
    for bad in (20.0, float("nan")):
        with pytest.raises(ValueError, match="options\\['cart'\\]"):
            env.reset(options={"cart": bad})


def test_cart_stem_contact_whipping_off_an_obstacle_misses_no_contact():
    """Bang-bang carts drag the beam over an obstacle and release it; its tip then whips at
    up to 0.9 m/s. The environment's margin must cover a step's travel (the robot's default
    3 mm warned 53 times over these episodes)."""
    from pliant.errors import ContactMarginWarning

    env = gym.make("pliant/CartStemContact-v0")
    rng = np.random.default_rng(0)
    with warnings.catch_warnings():
        warnings.simplefilter("error", ContactMarginWarning)
        for episode in range(4):
            env.reset(seed=episode)
            for k in range(30):
                if k % 5 == 0:
                    action = rng.choice([-1.0, 1.0], size=1)
                env.step(action)


DOCS = Path(__file__).parents[2] / "docs" / "environments.md"


@pytest.mark.parametrize("code", re.findall(r"```python\n(.*?)```", DOCS.read_text(), flags=re.S))
def test_docs_example_runs(code):
    exec(compile(code, str(DOCS), "exec"), {})


def test_docs_table_lists_every_registered_environment():
    rows = {line.split("|")[1].strip() for line in DOCS.read_text().splitlines() if "|" in line}
    assert set(ENVS) <= rows


def test_space_debris_success_counts_the_cube_faces_the_trunk_presses_on():
    from pliant.constraints.friction import ContactForces

    env = make("TrunkSpaceDebris", cube_sizes=(30.0,))
    env.reset(seed=0)
    base = env.unwrapped
    colliding = base.model.contacts.points.nodes[:, 0]  # the trunk's points are its nodes
    a, b, c = 10, 40, 70
    q = np.sqrt(0.5)
    turn = np.array([[q, -q, 0.0], [q, q, 0.0], [0.0, 0.0, 1.0]])  # 45 deg about z
    centre = np.array([60.0, 0.0, 150.0])
    base.state.rigid_rotations[0] = turn
    base.state.rigid_positions[0] = centre
    # In the cube's frame a and b beyond its +x face (in the world, one is beyond the cube's
    # extent in x, the other in y: faces are told in the cube's frame), c beyond its +z face.
    for point, local in ((a, [15.2, 10.0, 0.0]), (b, [15.2, -10.0, 1.0]), (c, [0.0, 3.0, 15.3])):
        base.state.positions[colliding[point]] = centre + turn @ np.array(local)
    cube = len(base.model.contacts.shapes)  # rigid bodies are numbered after the shapes

    def pressing(keys, forces):
        base.state.contact_forces = ContactForces(
            np.array(keys, dtype=np.int64).reshape(-1, 3), np.array(forces, dtype=float)
        )
        return base.faces_in_contact(), base._info()["is_success"]

    push = [[1.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 3.0]]
    assert pressing([], np.zeros((0, 3))) == (0, False)
    assert pressing([[a, cube, 0], [b, cube, 0]], push[:2]) == (1, False)  # one face: touching
    assert pressing([[a, cube, 0], [b, cube, 0], [c, cube, 0]], push) == (2, True)  # wrapped
    assert pressing([[a, cube, 0], [c, cube, 0]], [push[0], [0.0] * 3]) == (1, False)  # no force
    assert pressing([[a, 0, 0], [b, 0, 0]], push[:2]) == (0, False)  # on the hull, not the cube
    with pytest.raises(ValueError, match="grasp_faces"):
        make("TrunkSpaceDebris", grasp_faces=0)


@pytest.mark.parametrize(
    ("size", "z", "cables", "faces_success", "catch"),
    [
        # experiments/results/rl/trunk_debris_expert: the one catch the planner found (the long
        # +x cable pulled and held: the trunk's middle and its tip on opposite faces) ...
        (40.0, 85.0, [3], True, True),
        # ... and a pinning (both +x cables: the cube knocked onto the hull and held there).
        (30.0, 110.0, [3, 7], True, False),
    ],
)
def test_space_debris_catch_test_tells_a_catch_from_a_pinning(
    size, z, cables, faces_success, catch
):
    """Both end with the trunk on two faces of the cube, the environment's default success;
    only the catch holds opposite faces with the cube off the hull for the last steps."""
    from pliant.robots.trunk_debris import beside_trunk

    for success, expected in (("faces", faces_success), ("catch", catch)):
        env = gym.make(  # the environment's own steps (the quick variant's are coarser)
            "pliant/TrunkSpaceDebris-v0", cube_sizes=(size,), continuous_mode="increment",
            success=success,
        )  # fmt: skip
        env.reset(seed=0, options={"cube_size": size, "cube_position": beside_trunk(size, z, 15.0)})
        action = np.zeros(8, dtype=np.float32)
        action[cables] = 1.0
        for _ in range(50):
            _, _, terminated, _, info = env.step(action)  # truncated at 50 by the time limit
            assert not terminated and "diverged" not in info
        assert info["faces"] == 2 and info["is_success"] == expected
        assert info["on_hull"] != catch and info["opposite_faces"] == catch
        assert (info["held"] >= 5) == catch
    with pytest.raises(ValueError, match="success"):
        make("TrunkSpaceDebris", success="touch")
    with pytest.raises(ValueError, match="catch_steps"):
        make("TrunkSpaceDebris", success="catch", catch_steps=0)


def test_space_debris_expert_pulls_the_facing_cables_and_catches_a_large_cube():
    from pliant.envs.trunk_space_debris import expert, expert_action, pull_weights, sized_expert
    from pliant.robots.trunk_debris import beside_trunk

    # long cables 0-3 at +y, -x, -y, +x: the cube's direction picks them, cos-weighted
    assert np.allclose(pull_weights(np.array([50.0, 0.0, 80.0])), [0, 0, 0, 1, 0, 0, 0, 0])
    w = pull_weights(np.array([50.0, 50.0 * np.tan(np.radians(30.0)), 80.0]))
    assert np.allclose(w[:4], [np.tan(np.radians(30.0)), 0.0, 0.0, 1.0]) and not w[4:].any()
    # the same pull, 2 mm a step, in each action space of the environment
    targets = []
    for kwargs in ({"continuous_mode": "increment"}, {"continuous_mode": "absolute"},
                   {"action_type": "discrete"}):  # fmt: skip
        env = make("TrunkSpaceDebris", cube_sizes=(40.0,), action_scale=2.0, **kwargs)
        env.reset(seed=0, options={"cube_position": beside_trunk(40.0, 85.0, 15.0)})
        e = env.unwrapped
        e.commands = np.array([0, 0, 0, 34.0, 0, 0, 0, 0])  # one step from the end of its course
        targets.append(e.commands_for(expert_action(env)).actuators)
    assert np.allclose(targets, [[0, 0, 0, 35.0, 0, 0, 0, 0]] * 3)
    # the sized expert: half the rate for cubes under 37.5 mm
    for size, rate in ((35.0, 0.5), (40.0, 1.0)):
        env = make("TrunkSpaceDebris", cube_sizes=(size,), continuous_mode="increment")
        obs, _ = env.reset(seed=0, options={"cube_position": beside_trunk(size, 85.0, 15.0)})
        assert np.allclose(sized_expert(env)(obs), [0, 0, 0, rate, 0, 0, 0, 0])
    with pytest.raises(ValueError, match="rate"):
        expert_action(env, rate=0.0)
    # it catches the 40 mm cube beside the trunk's middle (opposite faces, off the hull)
    env = gym.make(
        "pliant/TrunkSpaceDebris-v0", cube_sizes=(40.0,), continuous_mode="increment",
        success="catch",
    )  # fmt: skip
    obs, _ = env.reset(seed=0, options={"cube_position": beside_trunk(40.0, 90.0, 18.0)})
    act = expert(env)
    for _ in range(50):
        obs, _, terminated, _, info = env.step(act(obs))
        assert not terminated
    assert info["is_success"] and info["held"] >= 30


def test_space_debris_losing_the_cube_is_charged_the_steps_left():
    # An escape distance below the cube's start: lost at the first step, 49 steps left of 50.
    env = make("TrunkSpaceDebris", cube_sizes=(30.0,), escape_distance=1.0, horizon=50)
    env.reset(seed=0)
    _, reward, terminated, _, info = env.step(np.zeros(8, dtype=np.float32))
    parts = info["reward_parts"]
    step = parts["approach"] + parts["deformation"] + parts["wrapping"]
    assert terminated and step < 0.0
    assert parts["lost"] == pytest.approx(49 * step) and reward == pytest.approx(50 * step)


@pytest.mark.parametrize("cables", [(0, 6), (0, 4), (0, 1, 5)])
def test_space_debris_cables_at_their_limits_invert_no_element(cables):
    env = gym.make("pliant/TrunkSpaceDebris-v0", continuous_mode="increment", cube_sizes=(20.0,))
    env.reset(seed=0)
    pull = np.zeros(8, dtype=np.float32)
    pull[list(cables)] = 1.0  # 2 mm a step: every cable at its limit within 18 steps
    for _ in range(22):
        _, _, _, truncated, info = env.step(pull)
        assert not truncated, info.get("diverged")
    limits = env.unwrapped.max_commands
    assert np.allclose(env.unwrapped.commands[list(cables)], limits[list(cables)])


def test_space_debris_refuses_a_snapshot_of_a_cube_size_it_does_not_have():
    env = make("TrunkSpaceDebris", cube_sizes=(25.0,))
    env.reset(seed=0)
    other = make("TrunkSpaceDebris")
    other.reset(seed=0, options={"cube_size": 20.0})
    with pytest.raises(EnvStateError, match="20.0 mm"):
        env.unwrapped.set_state(other.unwrapped.get_state())
    assert env.unwrapped.cube_size == 25.0
