"""Models of rigid bodies alone (no deformable body): free fall, a pendulum on a ball joint, a
body on a sliding joint, a cart and pole, contact; checked against closed forms."""

from __future__ import annotations

import numpy as np
import pytest

from pliant.constraints.contact import Contacts
from pliant.constraints.rigid_joints import AxisLock, BallJoint, RestSpring, SlidingJoint
from pliant.errors import ModelError, StateError
from pliant.fem.rigid import RigidBody, WorldForce
from pliant.geometry.collision import Box, Plane, Sphere
from pliant.model import Model
from pliant.solvers import ImplicitEuler

G = 9.81


def _run(model: Model, dt: float, steps: int, record=None):
    solver = ImplicitEuler(model, dt)
    state = model.rest_state()
    out = []
    for _ in range(steps):
        state = solver.step(state)
        if record is not None:
            out.append(record(state))
    return state, np.array(out)


@pytest.mark.parametrize("dt", [1e-2, 5e-3])
def test_free_fall_follows_the_closed_form_to_first_order(dt):
    """Symplectic Euler: v_n = -g t_n, z_n = -g h^2 n (n + 1) / 2 = -g t^2 / 2 - g h t / 2;
    the state has no nodes."""
    body = RigidBody(Sphere(0.1), 1.0, position=(0.0, 0.0, 0.0))
    model = Model(None, rigid_bodies=[body])
    n = 50
    state, _ = _run(model, dt, n)
    t = n * dt
    z = state.rigid_positions[0, 2]
    assert state.positions.shape == (0, 3)
    assert z == pytest.approx(-G * dt * dt * n * (n + 1) / 2, rel=1e-12)
    assert state.rigid_velocities[0, 2] == pytest.approx(-G * t, rel=1e-12)
    assert abs(z - (-G * t * t / 2)) == pytest.approx(G * dt * t / 2, rel=1e-9)
    np.testing.assert_array_equal(state.rigid_positions[0, :2], 0.0)


def test_pendulum_on_a_ball_joint_keeps_its_small_oscillation_period_and_length():
    """A ball of radius r on a rod of length d about a fixed pivot: T = 2 pi sqrt(I / (m g d)),
    I = 2/5 m r^2 + m d^2; the joint holds the length to the scheme's drift O((h w)^2 d)."""
    d, m, r, theta, dt = 0.5, 2.0, 0.1, 0.05, 2e-3
    start = np.array([d * np.sin(theta), 0.0, -d * np.cos(theta)])
    ball = RigidBody(Sphere(r), m, position=start)
    joint = BallJoint(ball, -start, None, (0.0, 0.0, 0.0))
    period = 2 * np.pi * np.sqrt((0.4 * m * r * r + m * d * d) / (m * G * d))
    steps = int(1.3 * period / dt)
    _, centres = _run(
        Model(None, rigid_bodies=[ball], joints=[joint]),
        dt,
        steps,
        lambda s: s.rigid_positions[0].copy(),
    )
    x = centres[:, 0]
    t = dt * (1 + np.arange(steps))
    down = np.flatnonzero((x[:-1] > 0) & (x[1:] <= 0))  # downward crossings, a period apart
    up = np.flatnonzero((x[:-1] < 0) & (x[1:] >= 0))
    crossings = [t[i] + dt * x[i] / (x[i] - x[i + 1]) for i in (down[0], up[0])]
    assert 2 * (crossings[1] - crossings[0]) == pytest.approx(period, rel=2e-3)
    length = np.linalg.norm(centres, axis=1)
    assert np.max(np.abs(length - d)) < 1e-6 * d
    assert np.max(np.abs(centres[:, 1])) < 1e-12  # stays in its plane


def test_sliding_joint_moves_the_body_only_along_its_line():
    """A body on an inclined line: speed along the line (g . a) t, no motion across it."""
    axis = np.array([1.0, 0.0, -1.0]) / np.sqrt(2.0)
    body = RigidBody(Box((0.1, 0.1, 0.1)), 1.0, position=(0.0, 0.0, 0.0))
    joint = SlidingJoint(body, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), axis)
    dt, n = 5e-3, 100
    state, _ = _run(Model(None, rigid_bodies=[body], joints=[joint]), dt, n)
    x, v = state.rigid_positions[0], state.rigid_velocities[0]
    along = G * np.sqrt(0.5)  # g . a
    assert v @ axis == pytest.approx(along * n * dt, rel=1e-9)
    assert np.linalg.norm(v - (v @ axis) * axis) < 1e-9
    assert np.linalg.norm(x - (x @ axis) * axis) < 1e-9
    assert np.abs(state.rigid_angular_velocities).max() < 1e-12


def test_cart_and_pole_keep_their_horizontal_momentum():
    """A cart on a horizontal slider and a pole on a ball joint at the cart, turning about z
    only (AxisLock): no horizontal force acts on the pair, so m_c v_c + m_p v_p stays 0 while
    the pole falls; pushing the cart (WorldForce) gives it the push's impulse."""
    cart = RigidBody(Box((0.5, 0.3, 0.3)), 1.0, position=(0.0, 0.0, 0.0), name="cart")
    pole = RigidBody(
        Box((0.05, 0.6, 0.05)),
        0.1,
        position=(0.05, 0.9, 0.0),
        rotation=np.array(
            [[np.cos(0.1), -np.sin(0.1), 0], [np.sin(0.1), np.cos(0.1), 0], [0, 0, 1]]
        ),
        name="pole",
    )
    pivot_world = np.array([0.0, 0.3, 0.0])
    joints = [
        SlidingJoint(cart, (0.0, 0.0, 0.0), (-5.0, 0.0, 0.0), (5.0, 0.0, 0.0)),
        AxisLock(cart, [0, 0, 0, 1, 1, 1]),
        BallJoint(cart, pivot_world, pole),
        AxisLock(pole, [0, 0, 0, 1, 1, 0]),
    ]
    model = Model(None, rigid_bodies=[cart, pole], joints=joints, gravity=(0.0, -G, 0.0))
    state, momenta = _run(
        model,
        5e-3,
        60,
        lambda s: 1.0 * s.rigid_velocities[0, 0] + 0.1 * s.rigid_velocities[1, 0],
    )
    assert np.abs(state.rigid_velocities[1]).max() > 0.1  # the pole fell
    assert np.max(np.abs(momenta)) < 1e-9
    cart.forces = [WorldForce((2.0, 0.0, 0.0))]
    try:
        pushed, _ = _run(model, 5e-3, 20)
    finally:
        cart.forces = []
    momentum = 1.0 * pushed.rigid_velocities[0, 0] + 0.1 * pushed.rigid_velocities[1, 0]
    assert momentum == pytest.approx(2.0 * 20 * 5e-3, rel=1e-9)


def test_rest_spring_oscillates_about_its_sag_at_its_period():
    """A ball on a RestSpring (k, angular k_t) under gravity: its centre oscillates about
    z = -m g / k with period 2 pi sqrt(m / k), its turn about z (started at 0.1 rad) with
    2 pi sqrt(I / k_t); implicit Euler's phase error is O((h w)^2)."""
    m, r, k, dt = 1.0, 0.1, 100.0, 1e-3
    inertia = 0.4 * m * r * r
    k_turn = inertia * 100.0  # the same w = 10 rad/s
    turned = np.array([[np.cos(0.1), -np.sin(0.1), 0], [np.sin(0.1), np.cos(0.1), 0], [0, 0, 1]])
    ball = RigidBody(Sphere(r), m, position=(0.0, 0.0, 0.0), rotation=turned)
    spring = RestSpring(ball, k, k_turn, rest_rotation=np.eye(3))
    period = 2 * np.pi * np.sqrt(m / k)
    steps = int(1.3 * period / dt)
    _, record = _run(
        Model(None, rigid_bodies=[ball], joints=[spring]),
        dt,
        steps,
        lambda s: (
            s.rigid_positions[0, 2] + m * G / k,
            np.arctan2(*s.rigid_rotations[0, 1::-1, 0]),
        ),
    )
    t = dt * (1 + np.arange(steps))
    for signal in record.T:
        down = np.flatnonzero((signal[:-1] > 0) & (signal[1:] <= 0))[0]
        up = np.flatnonzero((signal[:-1] < 0) & (signal[1:] >= 0))[0]
        at = [t[i] + dt * signal[i] / (signal[i] - signal[i + 1]) for i in (down, up)]
        assert 2 * abs(at[1] - at[0]) == pytest.approx(period, rel=1e-3)


def test_rigid_only_ball_comes_to_rest_on_a_plane():
    """Contact with a still shape of the model's Contacts: a ball dropped on a floor rests on
    it (gap within the contact tolerance)."""
    ball = RigidBody(Sphere(0.1), 1.0, position=(0.0, 0.0, 0.15))
    model = Model(None, rigid_bodies=[ball], contacts=Contacts([Plane()], margin=0.05))
    state, _ = _run(model, 5e-3, 80)
    assert state.rigid_positions[0, 2] == pytest.approx(0.1, abs=1e-6)
    assert abs(state.rigid_velocities[0, 2]) < 1e-6


def test_rigid_only_model_refuses_what_needs_a_body():
    ball = RigidBody(Sphere(0.1), 1.0)
    other = RigidBody(Sphere(0.1), 1.0)
    with pytest.raises(ModelError, match="needs rigid bodies"):
        Model(None)
    with pytest.raises(ModelError, match="not one of the rigid bodies"):
        Model(None, rigid_bodies=[ball], joints=[BallJoint(other, (0.0, 0.0, 0.1))])
    with pytest.raises(ModelError, match="two different bodies"):
        BallJoint(ball, (0.0, 0.0, 0.0), ball)
    with pytest.raises(ModelError, match="coincide"):
        SlidingJoint(ball, (0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (1.0, 0.0, 0.0))
    model = Model(None, rigid_bodies=[ball])
    solver = ImplicitEuler(model, 1e-2)
    with pytest.raises(ModelError, match="no actuators"):
        solver.step(model.rest_state(), [1.0])
    with pytest.raises(ModelError, match="first_order"):
        ImplicitEuler(model, 1e-2, first_order=True)
    with pytest.raises(StateError):
        solver.step(Model(None, rigid_bodies=[ball, other]).rest_state())
