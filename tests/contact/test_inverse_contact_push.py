"""Inverse control with contacts pushing an object (issue 3, item 4) and rigid-body drag."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from pliant.constraints.control import InverseControl
from pliant.errors import ModelError
from pliant.fem.rigid import RigidBody
from pliant.geometry.collision import Box, Sphere
from pliant.robots.trunk_cube import PushControl, trunk_push
from pliant.solvers import ImplicitEuler
from pliant.solvers.rigid import RigidSolver, RigidWorld


def test_drag_decays_a_free_body_as_implicit_euler_predicts() -> None:
    """Velocity damping c on a body with no gravity and no contact: each step divides the
    linear and angular velocity by 1 + h c (the damping force taken at the end of the step), so
    after N steps v = v0 / (1 + h c)^N, and the body stops short of v0 / c travelled."""
    c, h, steps = 20.0, 0.01, 50
    body = RigidBody(
        Sphere(2.0),
        0.01,
        velocity=(30.0, 0.0, 0.0),
        angular_velocity=(0.0, 0.0, 3.0),
        linear_damping=c,
        angular_damping=c,
    )
    world = RigidWorld([body], [], gravity=(0.0, 0.0, 0.0))
    solver = RigidSolver(world, dt=h)
    state = world.initial_state()
    for _ in range(steps):
        state = solver.step(state)
    decay = (1.0 + h * c) ** -steps
    np.testing.assert_allclose(state.velocities[0], [30.0 * decay, 0.0, 0.0], rtol=1e-12)
    np.testing.assert_allclose(state.angular_velocities[0], [0.0, 0.0, 3.0 * decay], rtol=1e-12)
    travelled = 30.0 * h * sum((1.0 + h * c) ** -k for k in range(1, steps + 1))
    assert state.positions[0, 0] == pytest.approx(travelled, rel=1e-12)
    assert travelled < 30.0 / c


def test_bad_drag_and_push_settings_raise() -> None:
    with pytest.raises(ModelError, match="damping"):
        RigidBody(Box([1.0, 1.0, 1.0]), 1.0, linear_damping=-1.0)
    with pytest.raises(ModelError, match="damping"):
        RigidBody(Box([1.0, 1.0, 1.0]), 1.0, angular_damping=float("nan"))
    with pytest.raises(ModelError, match="speed"):
        PushControl(np.zeros(3), speed=0.0)
    model = trunk_push()
    with pytest.raises(ModelError, match="seed_gap"):
        ImplicitEuler(model, 0.01).step(model.rest_state(), InverseControl(seed_gap=-1.0))


def test_the_trunk_pushes_the_cube_to_its_goal_and_keeps_in_contact() -> None:
    """QPCC (Eq. 2.15 with complementarity) with the cube as effector: the actuators move it
    only through the contacts (its rows have no Jacobian on the trunk). The trunk pushes it
    3 mm along x on its air table to within 0.2 mm, touching it (gap <= 0.05 mm) in at least
    90 % of the steps once it has touched it, with cable forces that only pull and courses
    within bounds; the cube moves only forwards."""
    model = trunk_push()
    solver = ImplicitEuler(model, 0.01)
    state = model.rest_state()
    cube = model.rigid_bodies[0]
    start = state.rigid_positions[0].copy()
    control = PushControl(start + np.array([3.0, 0.0, 0.0]))
    gaps, xs = [], []
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no unsettled contact states, no missed contacts
        for _ in range(120):
            state = solver.step(state, control)
            cube.shape.set_pose(state.rigid_positions[0], state.rigid_rotations[0])
            gaps.append(cube.shape.signed_distance(state.positions.reshape(-1, 3)).gap.min())
            xs.append(state.rigid_positions[0, 0] - start[0])
            assert np.all(state.actuation >= -1e-9)
            limits = [a.max_displacement for a in model.actuators]
            assert np.all(state.displacement <= np.array(limits) + 1e-6)
    gaps, xs = np.array(gaps), np.array(xs)
    assert abs(xs[-1] - 3.0) < 0.2
    assert np.all(np.diff(xs) > -1e-6)
    touched = int(np.argmax(gaps <= 0.05))
    assert gaps[touched] <= 0.05
    assert np.mean(gaps[touched:] <= 0.05) >= 0.9
    assert gaps.min() > -model.contacts.margin  # no deep penetration
