"""Physical checks of the scenes built for the environments: StemPendulum, BubbleMotion,
TrunkSpaceDebris."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from pliant.robots.bubble_motion import bubble_motion, demo_actuation
from pliant.robots.stem_pendulum import small_swing_period, stem_pendulum
from pliant.robots.trunk_debris import demo_actuation as trunk_debris_demo
from pliant.robots.trunk_debris import trunk_space_debris
from pliant.solvers import ImplicitEuler


def _turned(model, angle: float):
    """The stem's rest state turned by `angle` about the hinge (+y), at rest."""
    state = model.rest_state()
    n = model.body.n_centreline
    turn = Rotation.from_rotvec([0.0, angle, 0.0])
    state.positions[:n] = turn.apply(state.positions[:n])
    state.positions[n:] = (turn * Rotation.from_rotvec(state.positions[n:])).as_rotvec()
    return state


def test_stem_pendulum_swings_with_the_compound_pendulum_period():
    # T = 2 pi sqrt(2 L / 3 g) for a rigid uniform rod about one end (small swings, 3 deg: the
    # amplitude adds theta^2 / 16 = 0.02 %). The lumped masses of 10 elements overestimate the
    # inertia by 0.5 % (sum of i^2 h^3 + n^2 h^3 / 2 against n^3 h^3 / 3): about 0.25 % on T;
    # implicit Euler's period error is O((omega dt)^2) = 1e-4 at dt = 1 ms.
    model = stem_pendulum(rayleigh_stiffness=0.0)
    sim = ImplicitEuler(model, dt=1e-3)
    state = _turned(model, np.radians(3.0))
    tip, times = [], []
    for _ in range(1600):
        state = sim.step(state, np.zeros(3))
        tip.append(model.effectors[0].position(state.positions)[0, 0])
        times.append(state.time)
    tip, times = np.array(tip), np.array(times)
    up = np.flatnonzero((tip[:-1] < 0) & (tip[1:] >= 0))
    crossings = times[up] - tip[up] * (times[up + 1] - times[up]) / (tip[up + 1] - tip[up])
    period = np.diff(crossings).mean()
    assert len(crossings) >= 3
    assert abs(period / small_swing_period(100.0) - 1.0) < 0.01
    # The hinge keeps the swing in its plane.
    assert np.abs(state.positions[: model.body.n_centreline, 1]).max() < 1e-6


def test_stem_pendulum_holds_still_where_the_torque_balances_gravity():
    # Static balance of the motor's torque tau and the weight's moment: m g (L / 2) sin(theta)
    # = tau, so a torque of a fifth of m g L / 2 holds the stem at asin(0.2) from the vertical.
    model = stem_pendulum(rayleigh_mass=5.0)
    body = model.body
    mass = 1.0e-6 * 25.0 * 100.0
    tau = 0.2 * mass * 9810.0 * 50.0
    sim = ImplicitEuler(model, dt=0.01)
    state = model.rest_state()
    for _ in range(400):
        state = sim.step(state, np.array([tau, 0.0, 0.0]))
    tip = model.effectors[0].position(state.positions)[0]
    angle = np.arctan2(abs(tip[0]), -tip[2])
    assert abs(angle - np.arcsin(0.2)) < 0.01
    assert body.n_centreline == 11


def _top_heights(model, state) -> np.ndarray:
    """Height of the top face over each cavity's centre (nearest top node)."""
    rest = model.body.rest_positions
    heights = []
    for k in range(9):
        centre = model.body.mesh.landmarks[f"top_{k}"][0]
        node = int(np.argmin(np.linalg.norm(rest - centre, axis=1)))
        heights.append(state.positions[node, 2] - rest[node, 2])
    return np.array(heights)


def test_bubble_board_inflating_one_cavity_raises_the_top_over_it_only():
    model = bubble_motion(mesh_size=8.0, top_mesh_size=4.0, ball_position=(20.0, 20.0))
    sim = ImplicitEuler(model, dt=0.01)
    state = model.rest_state()
    pressures = np.zeros(9)
    pressures[1] = 30.0  # the middle cavity of the -y row
    for _ in range(60):
        state = sim.step(state, pressures)
    rise = _top_heights(model, state)
    assert rise[1] > 1.0  # a bubble of millimetres (4 mm at the default mesh)
    others = np.delete(rise, 1)
    assert np.abs(others).max() < 0.25 * rise[1]
    # The inflated cavity's volume grows; its pressure is the one imposed.
    assert state.displacement[1] > 0 and state.actuation[1] == pytest.approx(30.0)


def test_bubble_board_ball_rolls_off_a_bubble():
    # A ball on the flank of the centre bubble rolls away from it, down the slope.
    model = bubble_motion(ball_position=(10.0, 0.0))
    sim = ImplicitEuler(model, dt=0.01)
    state = model.rest_state()
    for _ in range(80):
        state = sim.step(state, demo_actuation(state.time))
    assert state.rigid_positions[0, 0] > 13.0


def test_space_debris_floats_without_gravity_and_a_push_sets_the_cube_drifting():
    model = trunk_space_debris()
    sim = ImplicitEuler(model, dt=0.01)
    state = model.rest_state()
    start = state.rigid_positions[0].copy()
    for _ in range(20):
        state = sim.step(state, np.zeros(8))
    # Nothing weighs: the trunk stays straight and the cube where it floats.
    np.testing.assert_allclose(state.positions, model.body.rest_positions, atol=1e-9)
    np.testing.assert_allclose(state.rigid_positions[0], start, atol=1e-12)
    for _ in range(40):
        state = sim.step(state, trunk_debris_demo(state.time))
    # Curled towards +x, the trunk has pushed the cube away along +x; once free it drifts.
    assert state.rigid_positions[0, 0] > start[0] + 10.0
    assert state.rigid_velocities[0, 0] > 0.0


def test_space_debris_cube_damping_slows_a_drifting_cube_as_rayleigh_mass_would():
    """A cube drifting away from the trunk at 100 mm/s under cube_damping c = 5 /s: implicit
    Euler's v_n = v_0 / (1 + c dt)^n; undamped it keeps its speed."""
    for damping, expected in ((5.0, 100.0 / 1.05**20), (0.0, 100.0)):
        model = trunk_space_debris(cube_damping=damping)
        sim = ImplicitEuler(model, dt=0.01)
        state = model.rest_state()
        state.rigid_velocities[0] = [100.0, 0.0, 0.0]
        for _ in range(20):
            state = sim.step(state, np.zeros(8))
        assert state.rigid_velocities[0, 0] == pytest.approx(expected, rel=1e-6)
