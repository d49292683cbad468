"""A rigid body's points against a deformable body's triangles (RigidSurfaceContact): a ball
resting on a soft block carries its weight without sinking into it, a dropped ball comes to
rest (on a massless board held by springs too, whose far face lies within the contact's reach),
and bad input is refused."""

from __future__ import annotations

import numpy as np
import pytest

from pliant.constraints import RigidSurfaceContact
from pliant.constraints.base import EmbeddedPoints
from pliant.constraints.contact import Contacts
from pliant.errors import ContactError
from pliant.fem.body import TetBody
from pliant.fem.loads import RestShapeSprings
from pliant.fem.material import Corotational
from pliant.fem.rigid import RigidBody
from pliant.geometry.collision import Sphere
from pliant.mesh import box_beam
from pliant.model import Model
from pliant.solvers import ImplicitEuler

G = 9810.0  # mm/s^2
RADIUS, MASS = 2.0, 2e-4  # mm, kg (a steel-like ball of 2 mm on a 100 kPa block)


def _ball_on_block(lift: float, *, friction: float = 0.0):
    """A 12 x 12 x 4 mm block held at its bottom, a ball of radius 2 mm `lift` above its top
    face (off its nodes: no node lies within the margin of the ball), the ball's centre
    against the block's boundary triangles."""
    mesh = box_beam(12.0, 12.0, 4.0, nx=3, ny=3, nz=1)
    body = TetBody(
        mesh,
        Corotational(100.0, 0.3),
        density=1e-6,
        fixed_nodes=np.flatnonzero(mesh.points[:, 2] < 1e-9),
        gravity=(0.0, 0.0, -G),
        rayleigh_mass=5.0,
    )
    ball = RigidBody(Sphere(RADIUS), MASS, position=(5.9, 6.3, 4.0 + RADIUS + lift))
    faces = body.boundary_triangles
    used, local = np.unique(faces, return_inverse=True)
    surface = RigidSurfaceContact(
        ball,
        np.zeros((1, 3)),
        EmbeddedPoints.at_nodes(used),
        local.reshape(-1, 3),
        friction=friction,
        radius=RADIUS,
    )
    contacts = Contacts([], rigid_surfaces=[surface], margin=0.5)
    return Model(body, contacts=contacts, rigid_bodies=[ball]), surface


def _gap(model: Model, surface: RigidSurfaceContact, state) -> float:
    found = surface.detect_rigid(
        state.positions, 1.0, 0, state.rigid_positions[0], state.rigid_rotations[0]
    )
    return float(found[0].gap.min())


@pytest.fixture(scope="module")
def resting():
    """The ball placed 0.01 mm above the block, stepped 150 x 10 ms (to rest; with
    friction, else it rolls about the dent it makes)."""
    model, surface = _ball_on_block(0.01, friction=0.5)
    solver = ImplicitEuler(model, 0.01)
    state = model.rest_state()
    for _ in range(150):
        state = solver.step(state)
    return model, surface, solver, state


def test_ball_resting_on_a_soft_block_carries_its_weight(resting) -> None:
    model, surface, solver, state = resting
    keys, forces = state.contact_forces.keys, state.contact_forces.forces
    on = keys[:, 1] == 2  # after the ball's shape (1) and no surface contact of pieces
    assert on.any()
    weight = MASS * G
    # The block's nodes near the ball (against its shape) carry nothing: it rests on faces.
    assert np.abs(forces[~on]).max(initial=0.0) < 1e-9 * weight
    np.testing.assert_allclose(forces[on, 2].sum(), weight, rtol=1e-5)
    assert np.abs(forces[on, :2].sum(axis=0)).max() < 1e-5 * weight
    # No penetration beyond the solver's tolerance, and the block is dented under the ball.
    assert _gap(model, surface, state) > -model.contacts.tolerance
    assert state.positions[:, 2].min() >= -1e-12
    assert solver.last_report.contact.converged
    assert np.abs(state.rigid_velocities).max() < 1e-3
    assert state.rigid_positions[0, 2] < 4.0 + RADIUS  # the block gave way under it


def test_dropped_ball_comes_to_rest_on_the_block() -> None:
    model, surface = _ball_on_block(1.0, friction=0.5)
    solver = ImplicitEuler(model, 0.01)
    state = model.rest_state()
    for _ in range(150):
        state = solver.step(state)
    assert np.abs(state.rigid_velocities).max() < 1e-2
    assert np.abs(state.velocities).max() < 1e-2
    assert _gap(model, surface, state) > -model.contacts.tolerance
    np.testing.assert_allclose(state.contact_forces.forces[:, 2].sum(), MASS * G, rtol=1e-3)


def _sphere_points(n: int, radius: float) -> np.ndarray:
    """`n` points spread over a sphere (a Fibonacci lattice), its poles included."""
    z = np.linspace(-1.0, 1.0, n)
    phi = np.pi * (3.0 - np.sqrt(5.0)) * np.arange(n)
    rho = np.sqrt(1.0 - z * z)
    return radius * np.column_stack([rho * np.cos(phi), rho * np.sin(phi), z])


def _ball_on_board(drop: float):
    """A massless board 12 x 12 x 1 mm held by rest-shape springs at its bottom nodes (SOFA's
    BubbleMotion board, massless and spring-held), a ball of 40 points on a 2 mm sphere
    `drop` above it. The board is thinner than the contact's reach at impact: the points near
    its top face see its bottom face too, from behind."""
    mesh = box_beam(12.0, 12.0, 1.0, nx=3, ny=3, nz=1)
    bottom = np.flatnonzero(mesh.points[:, 2] < 1e-9)
    body = TetBody(
        mesh,
        Corotational(1000.0, 0.3),
        mass="none",
        gravity=(0.0, 0.0, -G),
        loads=[RestShapeSprings(bottom, mesh.points, 1e4)],
    )
    ball = RigidBody(Sphere(RADIUS), MASS, position=(5.9, 6.3, 1.0 + RADIUS + drop))
    used, local = np.unique(body.boundary_triangles, return_inverse=True)
    surface = RigidSurfaceContact(
        ball,
        _sphere_points(40, RADIUS),
        EmbeddedPoints.at_nodes(used),
        local.reshape(-1, 3),
        friction=0.5,
        distance=0.01,
    )
    contacts = Contacts([], rigid_surfaces=[surface], margin=0.5)
    return Model(body, contacts=contacts, rigid_bodies=[ball]), surface


def test_ball_dropped_on_a_massless_board_stays_on_it() -> None:
    """Dropped 1 mm, the ball reaches the board at 140 mm/s (1.4 mm a step, more than the
    board's thickness): it stops on the board's top face, never pushed through it by the
    face beneath, and the board carries its weight to its springs."""
    model, surface = _ball_on_board(1.0)
    solver = ImplicitEuler(model, 0.01)
    state, lowest = model.rest_state(), np.inf
    for _ in range(60):
        state = solver.step(state)
        lowest = min(lowest, state.rigid_positions[0, 2])
        assert solver.last_report.contact is None or solver.last_report.contact.converged
    top = surface.vertices.positions(state.positions)[:, 2].max()
    assert lowest > 1.0 + RADIUS - 0.5  # it never sank half a millimetre into the board
    assert state.rigid_positions[0, 2] > top + 0.9 * RADIUS
    assert np.abs(state.rigid_velocities).max() < 1e-2
    assert _gap(model, surface, state) > -model.contacts.tolerance
    np.testing.assert_allclose(state.contact_forces.forces[:, 2].sum(), MASS * G, rtol=1e-4)


def test_bad_rigid_surface_contact_raises() -> None:
    model, surface = _ball_on_block(0.01)
    ball, vertices, triangles = surface.body, surface.vertices, surface.triangles
    with pytest.raises(ContactError, match="local points"):
        RigidSurfaceContact(ball, np.zeros((0, 3)), vertices, triangles)
    with pytest.raises(ContactError, match="radius"):
        RigidSurfaceContact(ball, np.zeros((1, 3)), vertices, triangles, radius=-1.0)
    with pytest.raises(ContactError, match="not a RigidSurfaceContact"):
        Contacts([], rigid_surfaces=[object()])
    other = RigidBody(Sphere(1.0), 1e-4, position=(0.0, 0.0, 50.0))
    stray = RigidSurfaceContact(other, np.zeros((1, 3)), vertices, triangles)
    with pytest.raises(ContactError, match="not one of the model's"):
        Model(model.body, contacts=Contacts([], rigid_surfaces=[stray]), rigid_bodies=[ball])
