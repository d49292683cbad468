"""Deformable points attached to a dynamic rigid body (pliant.constraints.attachment)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import ROD_E, ROD_L, dead_load, straight_rod

from pliant.constraints.attachment import Attachment, Weld
from pliant.constraints.base import EmbeddedPoints
from pliant.constraints.cable import CableActuator
from pliant.constraints.contact import Contacts
from pliant.constraints.control import InverseControl
from pliant.constraints.effector import PositionEffector
from pliant.errors import DivergenceError, ModelError
from pliant.fem.body import TetBody
from pliant.fem.material import Corotational
from pliant.fem.rigid import KinematicBody, RigidBody, rail
from pliant.geometry.collision import Box, Plane
from pliant.geometry.rotation import log_map
from pliant.mesh import box_beam
from pliant.model import Model
from pliant.solvers import ImplicitEuler, StaticSolver

G = 9810.0  # mm/s^2
E, AREA, LENGTH = 1000.0, 400.0, 100.0  # kPa, mm^2, mm


def _hanging_bar(block_mass: float = 0.02, bar_mass: float = 1e-6):
    """A 100 x 20 x 20 mm bar (E = 1000 kPa, nu = 0) held at x = 0, gravity along +x, and a
    rigid block attached to its end face x = 100."""
    mesh = box_beam(LENGTH, 20.0, 20.0, nx=10, ny=2, nz=2)
    held = np.flatnonzero(mesh.points[:, 0] <= 1e-9)
    end = np.flatnonzero(mesh.points[:, 0] >= LENGTH - 1e-9)
    body = TetBody(
        mesh,
        Corotational(E, 0.0),
        total_mass=bar_mass,
        mass="uniform",
        fixed_nodes=held,
        gravity=(G, 0.0, 0.0),
    )
    block = RigidBody(Box([5.0, 10.0, 10.0], position=[LENGTH + 5.0, 10.0, 10.0]), block_mass)
    attachment = Attachment(EmbeddedPoints.at_nodes(end), block)
    return Model(body, rigid_bodies=[block], attachments=[attachment]), block, attachment


def test_a_hanging_block_stretches_the_bar_by_its_weight():
    """With nu = 0 the bar under an end load F = m g is in uniform uniaxial stress, which the
    linear tetrahedra hold exactly: the block comes to rest F L / (E A) lower, plus the bar's
    own weight m_bar g L / (2 E A)."""
    model, block, attachment = _hanging_bar()
    state = model.rest_state()
    solver = ImplicitEuler(model, 0.01)
    for _ in range(100):
        state = solver.step(state)
    expected = (0.02 + 1e-6 / 2) * G * LENGTH / (E * AREA)
    moved = state.rigid_positions[0, 0] - (LENGTH + 5.0)
    assert moved == pytest.approx(expected, rel=1e-5)
    attachment.set_pose(state.rigid_positions[0], state.rigid_rotations[0])
    assert np.abs(attachment.distance(state.positions)).max() < 1e-9


def test_the_block_on_the_bar_oscillates_at_the_spring_mass_frequency():
    """Released unstretched, the block oscillates about its rest stretch with the period
    2 pi sqrt(m L / (E A)) of a mass on a spring (bar mass 1e-6 of the block's)."""
    model, _, _ = _hanging_bar()
    dt = 1e-5
    solver, state = ImplicitEuler(model, dt), model.rest_state()
    rest = 0.02 * G * LENGTH / (E * AREA)
    offsets = []
    for _ in range(3000):
        state = solver.step(state)
        offsets.append(state.rigid_positions[0, 0] - (LENGTH + 5.0) - rest)
    offsets = np.array(offsets)
    up = np.flatnonzero((offsets[:-1] < 0.0) & (offsets[1:] >= 0.0))
    assert up.size >= 2
    period = np.diff(up).mean() * dt
    assert period == pytest.approx(2 * math.pi * math.sqrt(0.02 * LENGTH / (E * AREA)), rel=2e-3)
    assert offsets.max() == pytest.approx(rest, rel=0.02)  # amplitude barely damped


def test_a_spinning_free_assembly_keeps_its_momentum_and_turns_as_one():
    """A free soft block with a rigid block attached, thrown spinning about z: the total linear
    momentum is conserved to round-off (the attachment forces act in pairs), the attached
    points stay on the rigid block (to the step's second-order drift), and the whole turns by
    about w t."""
    mesh = box_beam(40.0, 20.0, 20.0, nx=4, ny=2, nz=2)
    body = TetBody(mesh, Corotational(100.0, 0.3), total_mass=0.01)
    centre = np.array([45.0, 10.0, 10.0])
    block = RigidBody(Box([5.0, 10.0, 10.0], position=centre), 0.02)
    end = np.flatnonzero(mesh.points[:, 0] >= 40.0 - 1e-9)
    attachment = Attachment(EmbeddedPoints.at_nodes(end), block)
    model = Model(body, rigid_bodies=[block], attachments=[attachment])
    state = model.rest_state()
    masses = body.node_masses
    com = (masses @ mesh.points + 0.02 * centre) / (masses.sum() + 0.02)
    spin = np.array([0.0, 0.0, 3.0])
    state.velocities[:] = np.cross(spin, mesh.points - com) + [10.0, 0.0, 0.0]
    state.rigid_velocities[0] = np.cross(spin, centre - com) + [10.0, 0.0, 0.0]
    state.rigid_angular_velocities[0] = spin

    def momentum(s):
        return masses @ s.velocities + 0.02 * s.rigid_velocities[0]

    start = momentum(state)
    solver = ImplicitEuler(model, 1e-3)
    drift = 0.0
    for _ in range(500):
        state = solver.step(state)
        attachment.set_pose(state.rigid_positions[0], state.rigid_rotations[0])
        drift = max(drift, float(np.abs(attachment.distance(state.positions)).max()))
    assert np.abs(momentum(state) - start).max() < 1e-12 * np.abs(start).max()
    assert drift < 1e-4
    assert log_map(state.rigid_rotations[0])[2] == pytest.approx(1.5, rel=0.02)


def _cable_beam_with_payload(on_floor: bool):
    """A cable beam held at x = 0 carrying a rigid block attached under its free end; with
    `on_floor` the block hangs just above a floor it may touch."""
    mesh = box_beam(60.0, 10.0, 10.0, nx=6, ny=2, nz=2)
    held = np.flatnonzero(mesh.points[:, 0] <= 1e-9)
    body = TetBody(
        mesh,
        Corotational(300.0, 0.3),
        total_mass=0.005,
        fixed_nodes=held,
        gravity=(0.0, 0.0, -G),
        rayleigh_mass=2.0,
    )
    path = EmbeddedPoints(body.mesh, [[10.0, 5.0, 9.0], [30.0, 5.0, 9.0], [55.0, 5.0, 9.0]])
    cable = CableActuator(path, body.rest_positions, pull_point=[-5.0, 5.0, 9.0])
    block = RigidBody(Box([4.0, 4.0, 2.0], position=[55.0, 5.0, -2.0]), 0.002, friction=0.3)
    under = np.flatnonzero((mesh.points[:, 0] >= 50.0 - 1e-9) & (mesh.points[:, 2] <= 1e-9))
    attachment = Attachment(EmbeddedPoints.at_nodes(under), block)
    tip = PositionEffector(
        EmbeddedPoints(body.mesh, [[60.0, 5.0, 5.0]]),
        body.rest_positions,
        axes=(False, False, True),
    )
    contacts = (
        Contacts([Plane(point=(0.0, 0.0, -6.0))], friction=0.5, margin=1.0) if on_floor else None
    )
    return Model(
        body,
        actuators=[cable],
        effectors=[tip],
        contacts=contacts,
        rigid_bodies=[block],
        attachments=[attachment],
    )


def test_attachment_rows_from_kept_point_columns_give_the_step_of_every_column():
    """With contacts, the step reads the contact rows from the points' kept columns and solves
    the attachment rows with the free motion; from the same states it equals the step that
    solves every column (the payload pressed on the floor as the cable lifts and drops)."""
    model = _cable_beam_with_payload(on_floor=True)
    kept = ImplicitEuler(model, 0.01)
    every = ImplicitEuler(model, 0.01, point_compliance=False)
    state = model.rest_state()
    touched = 0
    for i in range(60):
        command = np.array([1.5 * math.sin(0.1 * i)])
        new, reference = kept.step(state, command), every.step(state, command)
        assert np.abs(new.positions - reference.positions).max() < 1e-6
        assert np.abs(new.rigid_positions - reference.rigid_positions).max() < 1e-6
        touched += len(new.contact_forces.keys) > 0
        state = new
    assert touched > 10


def test_inverse_control_moves_the_loaded_tip_to_its_goal():
    """The QP sees the body and its attached payload as one (the attachment rows eliminated):
    the tip's height, pulled by the cable under the payload's weight, reaches a goal 2 mm up."""
    model = _cable_beam_with_payload(on_floor=False)
    solver, state = ImplicitEuler(model, 0.01), model.rest_state()
    for _ in range(60):  # settle under the payload
        state = solver.step(state, np.zeros(1))
    goal = model.effectors[0].points.positions(state.positions) + [0.0, 0.0, 2.0]
    control = InverseControl(goal)
    for _ in range(150):
        state = solver.step(state, control)
    reached = model.effectors[0].points.positions(state.positions)
    assert abs(reached[0, 2] - goal[0, 2]) < 0.01
    assert state.actuation[0] > 0.0


def test_bad_attachments_raise():
    mesh = box_beam(20.0, 10.0, 10.0, nx=2, ny=1, nz=1)
    body = TetBody(mesh, Corotational(100.0, 0.3), total_mass=0.001)
    block = RigidBody(Box([2.0, 2.0, 2.0], position=[25.0, 5.0, 5.0]), 0.001)
    points = EmbeddedPoints.at_nodes(np.flatnonzero(mesh.points[:, 0] >= 20.0 - 1e-9))
    with pytest.raises(ModelError, match="not one of the model's rigid_bodies"):
        Model(body, attachments=[Attachment(points, block)])
    still = rail([0.0, 0.0, 0.0], [1.0, 0.0, 0.0], lambda t: 0.0)
    carriage = KinematicBody(Box([2.0, 2.0, 2.0]), still)
    with pytest.raises(ModelError, match="DrivenNodes"):
        Attachment(points, carriage)
    with pytest.raises(ModelError, match="no points"):
        Attachment(EmbeddedPoints.at_nodes(np.zeros(0, dtype=np.int64)), block)
    twice = Model(
        body,
        rigid_bodies=[block],
        attachments=[Attachment(points, block, name="a"), Attachment(points, block, name="b")],
    )
    with pytest.raises(DivergenceError, match="not positive definite"):
        ImplicitEuler(twice, 0.01).step(twice.rest_state())
    with pytest.raises(ModelError, match="rigid bodies"):
        StaticSolver(Model(body, rigid_bodies=[block], attachments=[Attachment(points, block)]))


# ---------------------------------------------------------------------------------------------
# A rod welded to a rigid body: position and orientation


def _welded_rod(kind: str):
    """A rod of 8 elements along +x (100 mm, radius 1, E = 1000 kPa, stiffness-proportional
    damping: rigid motions undamped) joined at node 0 to a 1000 kg hub, by a weld or by a pin
    (an Attachment of the node's position), a dead load pulling its tip along -z."""
    rod = straight_rod(8, clamped=[], rayleigh_stiffness=0.2)
    hub = RigidBody(Box([25.0, 25.0, 25.0], position=[-25.0, 0.0, 0.0]), 1e3, name="hub")
    link = (
        Weld(rod, [0], hub)
        if kind == "weld"
        else Attachment(EmbeddedPoints.at_nodes([0]), hub, name="pin")
    )
    load = dead_load(rod, 8, [0.0, 0.0, -1.0])
    return Model(rod, actuators=[load], rigid_bodies=[hub], attachments=[link]), rod


def test_a_rod_welded_to_a_hub_bends_as_a_cantilever_and_a_pinned_one_swings():
    """The weld holds the node's frame on the hub: under a tip load the rod settles on the
    clamped cantilever's static deflection, read in the hub's frame (measured 1.991801 mm
    against 1.991810 mm; the hub, 1e6 times heavier, barely moves). Held by its position
    alone, the rod turns about the pin and hangs from it."""
    probe = straight_rod(8)
    load = 0.02 * 3 * ROD_E * probe.section.inertia[0] / ROD_L**2  # 2 mm of deflection
    clamped = Model(probe, actuators=[dead_load(probe, 8, [0.0, 0.0, -1.0])])
    expected = StaticSolver(clamped).step(clamped.rest_state(), [load]).positions[8]
    tips = {}
    for kind in ("weld", "pin"):
        model, rod = _welded_rod(kind)
        solver, state = ImplicitEuler(model, 0.01), model.rest_state()
        for _ in range(600):
            state = solver.step(state, [load])
        hub_r, hub_c = state.rigid_rotations[0], state.rigid_positions[0]
        tips[kind] = hub_r.T @ (state.positions[8] - hub_c) + [-25.0, 0.0, 0.0]
        if kind == "weld":
            weld = model.attachments[0]
            weld.set_pose(hub_c, hub_r)
            assert np.abs(weld.orientation_error(state.positions)).max() < 1e-10
    assert expected[2] < -1.9
    assert np.abs(tips["weld"] - expected).max() < 1e-5 * abs(expected[2])
    assert tips["pin"][0] < 0.0  # turned past the hub's face: hanging from the pin


def test_bad_welds_raise():
    model, rod = _welded_rod("weld")
    hub = model.rigid_bodies[0]
    with pytest.raises(ModelError, match="rod nodes must lie"):
        Weld(rod, [9], hub)
    with pytest.raises(ModelError, match="twice"):
        Weld(rod, [0, 0], hub)
    mesh = box_beam(10.0, 2.0, 2.0, 2, 1, 1)
    tets = TetBody(mesh, Corotational(E, 0.3), total_mass=1e-6)
    with pytest.raises(ModelError, match="use Attachment"):
        Weld(tets, [0], hub)


def test_a_welded_rod_on_a_hub_resting_on_the_floor_carries_its_weight():
    """The welded node sits on the hub's face: it does not collide with the hub it is held by
    (that row would be the weld's own, with no compliance: W singular). The rod droops onto the
    floor; at rest the floor carries the hub and the rod (to 1e-9), the weld holds to 1e-12."""
    rod = straight_rod(8, clamped=[], rayleigh_mass=10.0, gravity=(0, 0, -G), density=1e-7)
    hub = RigidBody(Box([25.0, 25.0, 25.0], position=[-25.0, 0.0, 0.0]), 0.05, name="hub")
    contacts = Contacts([Plane(point=(0, 0, -25.0))], friction=0.5, margin=1.0, thickness=1.0)
    weld = Weld(rod, [0], hub)
    model = Model(rod, rigid_bodies=[hub], attachments=[weld], contacts=contacts)
    assert np.argwhere(contacts._carried).tolist() == [[0, 0]]
    solver, state = ImplicitEuler(model, 0.01), model.rest_state()
    for _ in range(300):
        state = solver.step(state)
    weight = (hub.mass + rod.total_mass) * G
    forces = state.contact_forces
    assert abs(forces.forces[:, 2].sum() - weight) < 1e-9 * weight
    assert 8 in forces.keys[:, 0]  # the tip rests on the floor
    weld.set_pose(state.rigid_positions[0], state.rigid_rotations[0])
    assert np.abs(weld.distance(state.positions)).max() < 1e-12
