"""Contact between two pieces of one deformable body (SurfaceContact): force balance, no
interpenetration, symmetric pieces, weight carried, Coulomb's stick/slip threshold."""

from __future__ import annotations

import numpy as np
import pytest

from pliant.constraints import SurfaceContact, body_pieces
from pliant.constraints.base import EmbeddedPoints
from pliant.constraints.contact import Contacts
from pliant.errors import ContactError, ContactMarginWarning
from pliant.fem.body import TetBody
from pliant.fem.loads import NodalForces, RestShapeSprings
from pliant.fem.material import Corotational
from pliant.fem.rigid import RigidBody
from pliant.geometry.collision import Plane, Sphere
from pliant.mesh import TetMesh, box_beam
from pliant.model import Model
from pliant.solvers import ImplicitEuler, StaticSolver

G = 9810.0  # mm/s^2


def _stack(bottom, top) -> tuple[TetMesh, np.ndarray, np.ndarray]:
    """The union of two meshes, and each one's nodes in it."""
    n = len(bottom.points)
    mesh = TetMesh(np.vstack([bottom.points, top.points]), np.vstack([bottom.tets, top.tets + n]))
    return mesh, np.arange(n), np.arange(n, n + len(top.points))


def _pressed(size_top: float, gap: float, *, friction: float = 0.0, load: float = 0.0):
    """A 6 mm block (12 x 12, bottom held) under a block of side `size_top`, `gap` above it,
    held sideways at its top face, that face pushed down by `load` mN in all; no gravity
    (the top block floats but for the contact: stepped to rest, not solved in statics)."""
    bottom = box_beam(12.0, 12.0, 6.0, nx=3, ny=3, nz=2)
    offset = 0.5 * (12.0 - size_top)
    top = box_beam(size_top, size_top, 6.0, nx=2, ny=2, nz=2, origin=(offset, offset, 6.0 + gap))
    mesh, a, b = _stack(bottom, top)
    z = mesh.points[:, 2]
    base = np.flatnonzero(z < 1e-9)
    face = b[z[b] > z[b].max() - 1e-9]
    sideways = np.concatenate([3 * face, 3 * face + 1])
    body = TetBody(
        mesh,
        Corotational(100.0, 0.3),
        density=1e-6,
        separate=True,
        fixed_nodes=base,
        fixed_dofs=sideways,
        loads=[NodalForces(face, (0.0, 0.0, -load / face.size))],
        gravity=(0.0, 0.0, 0.0),
        rayleigh_mass=20.0,
    )
    surface = SurfaceContact.between(body, b, a, friction=friction)
    return Model(body, contacts=Contacts([], surfaces=[surface], margin=1.0)), a, b


def _rest(model: Model, steps: int = 100):
    """The state after `steps` steps of 10 ms from rest (damped to equilibrium)."""
    solver = ImplicitEuler(model, 0.01)
    state = model.rest_state()
    for _ in range(steps):
        state = solver.step(state)
    assert np.abs(state.velocities).max() < 1e-3
    assert solver.last_report.contact.converged
    return state


def _deepest(model: Model, state) -> float:
    """The largest penetration of a piece into another at `state` (<= 0 when none)."""
    rows = model.contacts.surface_rows(state.positions)
    return max(0.0, -float(rows.contacts.gap.min()))


def test_pieces_of_a_body_are_found() -> None:
    model, a, b = _pressed(8.0, 0.1)
    pieces = body_pieces(model.body.tets, model.body.n_nodes)
    assert len(pieces) == 2
    np.testing.assert_array_equal(pieces[0], a)
    np.testing.assert_array_equal(pieces[1], b)


@pytest.mark.parametrize("friction", [0.0, 0.3])
def test_pressed_blocks_carry_the_load_without_interpenetration(friction: float) -> None:
    """At rest: the contact forces on the top block add up to the load pressing it (its only
    other supports are sideways), and no point of it ends inside the bottom block."""
    load = 300.0  # mN (kg mm / s^2): a few tenths of a mm on 6 mm of a 100 kPa block
    model, a, b = _pressed(8.0, 0.1, load=load, friction=friction)
    state = _rest(model)
    forces = state.contact_forces.forces
    assert len(forces) >= 9  # the top block's bottom face (3 x 3 nodes)
    np.testing.assert_allclose(forces[:, 2].sum(), load, rtol=1e-6)
    if friction:  # friction holds the top block's bottom against its Poisson bulge
        assert np.all(np.linalg.norm(forces[:, :2], axis=1) <= friction * forces[:, 2] + 1e-9)
    assert _deepest(model, state) < 1e-5
    under = a[np.abs(model.body.rest_positions[a, 2] - 6.0) < 1e-9]
    assert state.positions[under, 2].min() < 6.0 - 0.1  # the bottom block was pressed


@pytest.mark.parametrize("friction", [0.0, 0.3])
def test_static_pressed_blocks_balance_the_load(friction: float) -> None:
    """Statics (StaticSolver): the top block, held sideways at its top face and pressed down by
    `load` there, is held up by the contact and by weak springs (k) on that face, its only
    vertical supports: the contact forces equal the load less the springs' k |u|, to
    round-off; no point ends inside the bottom block."""
    load, k = 300.0, 1.0  # mN, mN/mm per node
    bottom = box_beam(12.0, 12.0, 6.0, nx=3, ny=3, nz=2)
    top = box_beam(8.0, 8.0, 6.0, nx=2, ny=2, nz=2, origin=(2.0, 2.0, 6.1))
    mesh, a, b = _stack(bottom, top)
    z = mesh.points[:, 2]
    face = b[z[b] > z[b].max() - 1e-9]
    body = TetBody(
        mesh,
        Corotational(100.0, 0.3),
        density=1e-6,
        separate=True,
        fixed_nodes=np.flatnonzero(z < 1e-9),
        fixed_dofs=np.concatenate([3 * face, 3 * face + 1]),
        loads=[
            NodalForces(face, (0.0, 0.0, -load / face.size)),
            RestShapeSprings(face, mesh.points, k),
        ],
        gravity=(0.0, 0.0, 0.0),
    )
    surface = SurfaceContact.between(body, b, a, friction=friction)
    model = Model(body, contacts=Contacts([], surfaces=[surface], margin=1.0))
    state = StaticSolver(model).step(model.rest_state())
    sunk = state.positions[face, 2] - z[face]
    assert sunk.mean() < -0.3  # the gap closed, the blocks pressed
    springs = -k * sunk.sum()
    np.testing.assert_allclose(state.contact_forces.forces[:, 2].sum(), load - springs, rtol=1e-9)
    assert springs < 0.05 * load
    assert _deepest(model, state) < 1e-5


def test_symmetric_pieces_move_symmetrically() -> None:
    """Two identical blocks overlapping by half their length, the second the first turned
    half a turn about a horizontal axis (mesh included), pressed together by equal and
    opposite loads on their outer faces (held sideways there), each block's points against
    the other's surface, friction mu = 1: the problem is symmetric under that half turn, so
    each node of one block moves as the turned motion of its image in the other."""
    load = 300.0  # mN
    bottom = box_beam(8.0, 8.0, 6.0, nx=2, ny=2, nz=2)
    turn = np.array([-1.0, 1.0, -1.0])  # half a turn about y through (5.5, ., 6.005)
    top = TetMesh(bottom.points * turn + [11.0, 0.0, 12.01], bottom.tets)
    mesh, a, b = _stack(bottom, top)
    z = mesh.points[:, 2]
    base, face = np.flatnonzero(z < 1e-9), b[z[b] > 12.01 - 1e-9]
    outer = np.concatenate([base, face])
    body = TetBody(
        mesh,
        Corotational(100.0, 0.3),
        density=1e-6,
        separate=True,
        fixed_dofs=np.concatenate([3 * outer, 3 * outer + 1]),
        loads=[
            NodalForces(base, (0.0, 0.0, load / base.size)),
            NodalForces(face, (0.0, 0.0, -load / face.size)),
        ],
        gravity=(0.0, 0.0, 0.0),
        rayleigh_mass=20.0,
    )
    surfaces = [
        SurfaceContact.between(body, b, a, friction=1.0),
        SurfaceContact.between(body, a, b, friction=1.0),
    ]
    model = Model(body, contacts=Contacts([], surfaces=surfaces, margin=1.0))
    state = _rest(model, 300)
    u = state.positions - mesh.points
    scale = np.abs(u).max()
    assert np.abs(u[a, 2]).max() > 0.1
    np.testing.assert_allclose(u[b], u[a] * turn, atol=1e-3 * scale)
    # The forces on the top block's points (pair 1) and on the bottom block's (pair 2) carry
    # the load together, half each by symmetry.
    forces, pair = state.contact_forces.forces, state.contact_forces.keys[:, 1]
    up, down = forces[pair == 1, 2].sum(), -forces[pair == 2, 2].sum()
    np.testing.assert_allclose(up + down, load, rtol=1e-6)
    np.testing.assert_allclose(up, down, rtol=1e-3)
    assert _deepest(model, state) < 1e-5


@pytest.mark.parametrize("with_rigid", [False, True])
def test_block_resting_on_a_block_carries_its_weight(with_rigid: bool) -> None:
    """Dynamics under gravity: a free block dropped 0.05 mm onto a held one comes to rest; the
    contact forces then add up to its weight. With a rigid ball resting on a floor beside
    them, the rows are coupled to the rigid bodies' (CoupledContact): the blocks' rows read
    no twist, and the floor carries the ball."""
    bottom = box_beam(12.0, 12.0, 4.0, nx=3, ny=3, nz=1)
    top = box_beam(6.0, 6.0, 6.0, nx=2, ny=2, nz=2, origin=(3.0, 3.0, 4.05))
    mesh, a, b = _stack(bottom, top)
    body = TetBody(
        mesh,
        Corotational(100.0, 0.3),
        density=1e-6,
        separate=True,
        fixed_nodes=np.flatnonzero(mesh.points[:, 2] < 1e-9),
        gravity=(0.0, 0.0, -G),
        rayleigh_mass=5.0,
    )
    surface = SurfaceContact.between(body, b, a, friction=0.5)
    ball = RigidBody(Sphere(2.0), 1e-4, position=(40.0, 40.0, 2.0), friction=0.5)
    rigid = {"rigid_bodies": [ball]} if with_rigid else {}
    shapes = [Plane()] if with_rigid else []
    model = Model(body, contacts=Contacts(shapes, surfaces=[surface], margin=0.5), **rigid)
    solver = ImplicitEuler(model, 0.01)
    state = model.rest_state()
    for _ in range(120):
        state = solver.step(state)
    weight = float(body.node_masses[b].sum()) * G
    keys, forces = state.contact_forces.keys, state.contact_forces.forces
    between = keys[:, 1] == len(shapes) + len(model.rigid_bodies) + 1
    np.testing.assert_allclose(forces[between, 2].sum(), weight, rtol=1e-5)
    on = forces[between]
    assert np.abs(on[:, :2].sum(axis=0)).max() < 1e-5 * weight
    assert np.all(np.linalg.norm(on[:, :2], axis=1) <= 0.5 * on[:, 2] + 1e-9)
    if with_rigid:
        np.testing.assert_allclose(forces[~between, 2].sum(), 1e-4 * G, rtol=1e-5)
    assert _deepest(model, state) < 1e-5
    assert np.abs(state.velocities).max() < 1e-3
    assert solver.last_report.contact.converged


def _sheared(push: float):
    """The pressed pair of `_pressed` (load 2 mN) with a sideways push on the top block's top
    face (held vertically by the load only): statics with friction mu = 0.4."""
    bottom = box_beam(12.0, 12.0, 6.0, nx=3, ny=3, nz=2)
    top = box_beam(8.0, 8.0, 6.0, nx=2, ny=2, nz=2, origin=(2.0, 2.0, 6.0))
    mesh, a, b = _stack(bottom, top)
    z = mesh.points[:, 2]
    face = b[z[b] > 12.0 - 1e-9]
    body = TetBody(
        mesh,
        Corotational(100.0, 0.3),
        density=1e-6,
        separate=True,
        fixed_nodes=np.flatnonzero(z < 1e-9),
        fixed_dofs=3 * face + 1,  # y held: the push is along x
        loads=[NodalForces(face, (push / face.size, 0.0, -2.0 / face.size))],
        gravity=(0.0, 0.0, 0.0),
        rayleigh_mass=20.0,
    )
    surface = SurfaceContact.between(body, b, a, friction=0.4)
    return Model(body, contacts=Contacts([], surfaces=[surface], margin=0.5)), a, b


@pytest.mark.parametrize(("push", "sticks"), [(0.5, True), (1.2, False)])
def test_friction_holds_below_mu_n_and_slips_above(push: float, sticks: bool) -> None:
    """A sideways push below mu N = 0.8 mN (N = 2 mN) is held by friction (the top block's
    bottom stays on the bottom block's top where it touched); above it, the block slides
    on: the friction force is then mu N, opposing the slip."""
    model, a, b = _sheared(push)
    solver = ImplicitEuler(model, 0.01)
    state = model.rest_state()
    for _ in range(60):
        state = solver.step(state)
    forces = state.contact_forces.forces
    normal = forces[:, 2].sum()
    bottom_of_top = b[np.abs(model.body.rest_positions[b, 2] - 6.0) < 1e-9]
    slid = state.positions[bottom_of_top, 0] - state.positions[a, 0].max() + 12.0
    travel = np.mean(
        state.positions[bottom_of_top, 0] - model.body.rest_positions[bottom_of_top, 0]
    )
    if sticks:
        np.testing.assert_allclose(normal, 2.0, rtol=1e-3)
        np.testing.assert_allclose(-forces[:, 0].sum(), push, rtol=1e-3)
        assert abs(travel) < 0.05
    else:
        assert slid.size and travel > 1.0  # sliding on
        np.testing.assert_allclose(-forces[:, 0].sum(), 0.4 * normal, rtol=1e-6)


def test_surface_contact_refuses_bad_input() -> None:
    model, a, b = _pressed(8.0, 0.1)
    body = model.body
    with pytest.raises(ContactError, match="share node"):
        SurfaceContact.between(body, np.concatenate([a, b]), a)
    with pytest.raises(ContactError, match="index"):
        SurfaceContact(EmbeddedPoints.at_nodes(b), EmbeddedPoints.at_nodes(a), [[0, 1, 10**6]])
    with pytest.raises(ContactError, match="contact distance"):
        SurfaceContact.between(body, b, a, distance=-1.0)
    with pytest.raises(ContactError, match="SurfaceContact"):
        Contacts([Plane()], surfaces=["not one"])


def test_obstacle_rows_come_first_and_keep_their_identity() -> None:
    """With an obstacle too, the obstacle's contacts are those it would have alone (same
    keys, same gaps), and the surface's follow them."""
    model, a, b = _pressed(8.0, 0.1)
    body = model.body
    floor = Plane(normal=(1.0, 0.0, 0.0), point=(-0.5, 0.0, 0.0))  # beside the bottom block
    alone = Contacts([floor], margin=1.0)
    alone.attach(body)
    both = Contacts([floor], margin=1.0, surfaces=model.contacts.surfaces)
    both.attach(body)
    x = body.rest_positions
    first = alone.constraint(x, None)
    joined = both.constraint(x, None)
    k = len(first.contacts)
    np.testing.assert_array_equal(joined.contacts.keys[:k], first.contacts.keys)
    np.testing.assert_array_equal(joined.distance(x)[: 3 * k], first.distance(x))
    rest = joined.contacts.take(np.arange(k, len(joined.contacts)))
    assert len(rest) == 9 and np.all(rest.index_b == 2)
    np.testing.assert_allclose(rest.gap, 0.1, atol=1e-12)
    assert k > 0 and np.all(first.contacts.index_b == 0)


def test_a_piece_moving_further_than_the_margin_onto_another_warns() -> None:
    """A block thrown at 150 mm/s onto another (1.5 mm a step, the margin 0.5 mm) ends a step
    near it having moved further than the margin: contacts may have been missed."""
    model, a, b = _pressed(8.0, 1.0)
    solver = ImplicitEuler(model, 0.01)
    state = model.rest_state()
    state.velocities[b, 2] = -150.0
    model.contacts.margin = 0.5
    with pytest.warns(ContactMarginWarning, match="closer to the surface it ends near"):
        for _ in range(3):
            state = solver.step(state)
