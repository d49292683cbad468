"""Deformable bodies in contact: the step's Signorini-Coulomb rows against closed forms and an
independent solve without contact."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from conftest import clamped_body, two_cable_beam

from pliant.constraints.base import Actuator, JacobianRows
from pliant.constraints.contact import Contacts
from pliant.constraints.control import InverseControl
from pliant.errors import ContactError, ContactMarginWarning
from pliant.fem.body import TetBody
from pliant.fem.material import Corotational
from pliant.geometry.collision import Box, Plane
from pliant.mesh import TetMesh, box_beam
from pliant.model import Model, State
from pliant.solvers import ImplicitEuler, StaticSolver

G = 9810.0  # mm/s^2


def _cube(lift: float = 0.2, friction: float = 0.5, **contact) -> Model:
    """A 20 mm soft cube (E = 100 kPa, 8 g) held `lift` mm above the floor z = 0."""
    mesh = box_beam(20.0, 20.0, 20.0, nx=3, ny=3, nz=3)
    mesh = TetMesh(mesh.points + [0.0, 0.0, lift], mesh.tets)
    body = TetBody(
        mesh,
        Corotational(100.0, 0.3),
        density=1e-6,
        gravity=(0.0, 0.0, -G),
        rayleigh_mass=5.0,
    )
    return Model(body, contacts=Contacts([Plane()], friction=friction, margin=1.0, **contact))


def test_cube_resting_on_the_floor_carries_its_weight() -> None:
    """At rest the normal contact forces add up to m g (equilibrium of the whole body) and no
    node is below the floor by more than the solver tolerance."""
    model = _cube()
    solver = ImplicitEuler(model, 0.01)
    state = model.rest_state()
    for _ in range(150):
        state = solver.step(state)
    weight = model.body.total_mass * G
    forces = state.contact_forces.forces
    assert len(forces) == 16  # the nodes of the bottom face (4 x 4)
    assert abs(forces[:, 2].sum() - weight) < 1e-6 * weight
    # Friction holds the bottom face against its Poisson bulge: tangential forces within the
    # cones, and no net sideways force.
    assert np.abs(forces[:, :2].sum(axis=0)).max() < 1e-6 * weight
    assert np.all(np.linalg.norm(forces[:, :2], axis=1) <= 0.5 * forces[:, 2] + 1e-9)
    assert state.positions[:, 2].min() > -model.contacts.tolerance
    assert np.abs(state.velocities).max() < 1e-6
    report = solver.last_report.contact
    assert report is not None and report.converged


def test_cube_dropped_on_the_floor_loses_energy_and_comes_to_rest() -> None:
    """Released 2 mm above the floor: kinetic + gravitational + elastic energy never grows
    (contacts and implicit Euler only dissipate) and the cube ends at rest on the floor."""
    model = _cube(lift=2.0, friction=0.3)
    model.contacts.margin = 2.5
    solver = ImplicitEuler(model, 0.005)
    state = model.rest_state()
    body = model.body
    masses = body.node_masses

    def energy(s: State) -> float:
        kinetic = 0.5 * float(np.sum(masses[:, None] * s.velocities**2))
        potential = float(np.sum(masses * G * s.positions[:, 2]))
        return kinetic + potential + body.linearise(s.positions).energy

    energies = [energy(state)]
    for _ in range(200):
        state = solver.step(state)
        energies.append(energy(state))
    # Energy can only appear through the contact solver's residual: each contact force (at
    # most the weight) may work over at most the solver tolerance per step.
    allowance = model.body.total_mass * G * model.contacts.tolerance * 16
    increase = np.diff(energies).max()
    assert increase <= allowance, f"energy grew by {increase:.3g} > {allowance:.3g}"
    assert abs(state.positions[:, 2].min()) < 1e-4
    assert np.abs(state.velocities).max() < 1e-2


class _NormalDisplacement(Actuator):
    """Imposes z(node) - z_rest(node) = value: the wall's push on one node, without contact."""

    def __init__(self, node: int, rest_z: float) -> None:
        super().__init__(name=f"push_{node}", mode="displacement", min_force=-np.inf)
        self.node, self.rest_z = node, rest_z

    def distance(self, x: np.ndarray) -> np.ndarray:
        return np.array([x[self.node, 2] - self.rest_z])

    def jacobian(self, x: np.ndarray) -> JacobianRows:
        return JacobianRows(np.array([[self.node]]), np.array([[[0.0, 0.0, 1.0]]]))


def test_cantilever_pressed_on_a_wall_matches_imposed_displacements() -> None:
    """A cantilever sags under gravity onto a frictionless block under its tip. The contact
    forces equal the reactions of a static solve without contact that imposes, on the nodes
    found in contact, their final height (an independent path: the direct solve on actuator
    rows instead of the Gauss-Seidel contact solver)."""
    mesh = box_beam(60.0, 8.0, 8.0, nx=12, ny=2, nz=2)
    material = Corotational(300.0, 0.3)
    wall = Box([4.0, 10.0, 5.0], position=[56.0, 4.0, -5.0 - 1.5])  # top face at z = -1.5
    body = clamped_body(mesh, material, density=1e-6, gravity=(0.0, 0.0, -G))
    free_sag = StaticSolver(Model(body)).step(Model(body).rest_state()).positions[:, 2].min()
    assert free_sag < -2.0, "the beam must reach the block"

    model = Model(body, contacts=Contacts([wall], friction=0.0, margin=0.5))
    contact_state = StaticSolver(model).step(model.rest_state())
    forces = contact_state.contact_forces
    touching = forces.forces[:, 2] > 1e-9
    nodes = forces.keys[touching, 0]
    nodes = model.contacts.points.nodes[nodes, 0]
    assert nodes.size >= 2
    assert contact_state.positions[:, 2].min() > -1.5 - 1e-6

    pushes = [_NormalDisplacement(int(n), body.rest_positions[n, 2]) for n in nodes]
    reference = Model(
        clamped_body(mesh, material, density=1e-6, gravity=(0.0, 0.0, -G)), actuators=pushes
    )
    reference.set_actuation(contact_state.positions[nodes, 2] - body.rest_positions[nodes, 2])
    imposed = StaticSolver(reference).step(reference.rest_state())
    reactions = imposed.actuation
    assert np.all(reactions > 0.0)  # the wall only pushes
    np.testing.assert_allclose(forces.forces[touching, 2], reactions, rtol=1e-5)
    np.testing.assert_allclose(contact_state.positions, imposed.positions, atol=1e-6)


def test_contact_state_round_trip_replays_exactly(tmp_path) -> None:
    """Contact forces are part of the state (the warm start): a saved and restored state
    replays the same steps bit for bit."""
    model = _cube(lift=1.0)
    solver = ImplicitEuler(model, 0.01)
    state = model.rest_state()
    for _ in range(15):
        state = solver.step(state)
    assert len(state.contact_forces.keys)
    state.save(tmp_path / "s.npz")
    restored = State.load(tmp_path / "s.npz")
    a, b = state, restored
    for _ in range(5):
        solver.system.invalidate()
        a = solver.step(a)
    other = ImplicitEuler(model, 0.01)
    for _ in range(5):
        other.system.invalidate()
        b = other.step(b)
    assert np.array_equal(a.positions, b.positions)
    assert np.array_equal(a.contact_forces.forces, b.contact_forces.forces)


def test_contact_solver_that_does_not_converge_warns_with_its_residual() -> None:
    model = _cube(lift=0.0, max_iterations=2)
    with pytest.warns(Warning, match="residual"):
        ImplicitEuler(model, 0.01).step(model.rest_state())


def test_bad_contact_input_raises() -> None:
    with pytest.raises(ContactError, match="overlaps"):
        _cube(lift=-3.0)
    with pytest.raises(ContactError, match="friction"):
        _cube(friction=-0.1)
    with pytest.raises(ContactError, match="margin"):
        Contacts([Plane()], margin=0.0)
    with pytest.raises(ContactError, match="at least one shape"):
        Contacts([])


def test_thick_points_rest_at_their_thickness_on_the_floor_and_under_a_body() -> None:
    """Colliding points that are balls of radius r (Contacts(thickness=r), a rod's nodes): the
    soft cube, with a rigid box lying on it, settles with its bottom nodes at height r and the
    box's underside r above the nodes under it (within the solver tolerance), and the floor
    carries the weight of both."""
    from pliant.fem.rigid import RigidBody

    r, lift = 1.5, 0.2
    body = _cube(lift=r + lift).body
    box = RigidBody(Box([6.0, 6.0, 3.0], position=[10.0, 10.0, 20.0 + 2 * (r + lift) + 3.0]), 0.002)
    contacts = Contacts([Plane()], friction=0.5, margin=1.0, thickness=r)
    model = Model(body, contacts=contacts, rigid_bodies=[box])
    solver = ImplicitEuler(model, 0.01)
    state = model.rest_state()
    for _ in range(300):
        state = solver.step(state)
    keys, forces = state.contact_forces.keys, state.contact_forces.forces
    nodes = contacts.points.nodes[keys[:, 0], 0]
    on_floor = keys[:, 1] == 0
    assert np.count_nonzero(on_floor) == 16 and np.count_nonzero(~on_floor) == 4
    tolerance = contacts.tolerance
    assert np.abs(state.positions[nodes[on_floor], 2] - r).max() < tolerance
    box.shape.set_pose(state.rigid_positions[0], state.rigid_rotations[0])
    gaps = box.shape.signed_distance(state.positions[nodes[~on_floor]]).gap - r
    assert np.abs(gaps).max() < tolerance
    weight = (body.total_mass + box.mass) * G
    assert abs(forces[on_floor, 2].sum() - weight) < 1e-5 * weight
    assert solver.last_report.contact.converged


def test_bad_contact_thickness_raises() -> None:
    for thickness in (-0.1, float("nan"), float("inf")):
        with pytest.raises(ContactError, match="thickness"):
            Contacts([Plane()], thickness=thickness)
    # The overlap check at the start counts the thickness: nodes 0.2 above the floor are
    # balls 2.3 into it, deeper than the margin.
    with pytest.raises(ContactError, match="overlaps"):
        _cube(lift=0.2, thickness=2.5)


def _cable_beam_under_a_wall(with_wall: bool) -> Model:
    """The two-cable beam (courses 8 mm); optionally a block above the tip whose underside is
    4 mm over the beam (z = 14)."""
    wall = Box([6.0, 10.0, 5.0], position=[55.0, 5.0, 19.0])
    contacts = Contacts([wall], friction=0.3, margin=5.0) if with_wall else None
    return two_cable_beam(max_displacement=8.0, contacts=contacts)


def _inverse_run(model: Model, goal: np.ndarray, steps: int = 60) -> tuple[State, ImplicitEuler]:
    solver, state = ImplicitEuler(model, 0.02), model.rest_state()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ContactMarginWarning)  # the first, free, step is long
        for _ in range(steps):
            state = solver.step(state, InverseControl(goals=[goal]))
    return state, solver


def test_inverse_control_with_contacts_presses_on_the_wall_instead_of_crossing_it() -> None:
    """Eq. 2.15 with complementarity: the goal lies past a wall; without it the tip reaches the
    goal, with it the beam stops on the wall (no point beyond it), pushed by the wall, and the
    QP settles on the closest reachable configuration."""
    goal = np.array([[56.0, 5.0, 14.0]])
    free, _ = _inverse_run(_cable_beam_under_a_wall(False), goal)
    model = _cable_beam_under_a_wall(True)
    blocked, solver = _inverse_run(model, goal)
    # The cables bend the beam in z (it also twists a little in y): compare heights.
    free_error = abs(model.effectors[0].position(free.positions)[0, 2] - goal[0, 2])
    blocked_error = abs(model.effectors[0].position(blocked.positions)[0, 2] - goal[0, 2])
    assert free.positions[:, 2].max() > 16.0  # without the wall the beam passes z = 14
    assert free_error < 0.5
    assert blocked.positions[:, 2].max() < 14.0 + model.contacts.tolerance  # solver tolerance
    assert blocked_error > 2.0
    forces = blocked.contact_forces.forces
    assert forces[:, 2].sum() < 0.0 and np.all(forces[:, 2] <= 1e-9)  # the wall only pushes
    assert np.all(blocked.actuation >= 0.0)
    assert np.all(blocked.displacement <= 8.0 + 1e-6)
    assert solver.last_report.contact.converged


def test_inverse_control_away_from_obstacles_ignores_them() -> None:
    """A goal away from the wall (bending down, its contact rows open all along): the same
    steps as with no obstacle at all."""
    goal = np.array([[57.0, 5.0, 0.0]])
    free, _ = _inverse_run(_cable_beam_under_a_wall(False), goal, steps=30)
    near, _ = _inverse_run(_cable_beam_under_a_wall(True), goal, steps=30)
    assert near.positions[:, 2].max() < 14.0
    np.testing.assert_allclose(near.positions, free.positions, atol=1e-6)


def test_a_step_longer_than_the_margin_warns() -> None:
    from pliant.errors import ContactMarginWarning

    model = _cube(lift=0.5)
    model.contacts.margin = 1e-3
    state = model.rest_state()
    state.velocities[:] = [0.0, 0.0, -200.0]  # 2 mm in one step of 0.01 s
    with pytest.warns(ContactMarginWarning, match="more than the contact margin"):
        ImplicitEuler(model, 0.01).step(state)


def test_a_long_step_far_from_every_obstacle_does_not_warn() -> None:
    import warnings

    from pliant.errors import ContactMarginWarning

    model = _cube(lift=20.0)
    model.contacts.margin = 1e-3
    state = model.rest_state()
    state.velocities[:] = [0.0, 0.0, -200.0]  # 2 mm in one step, ending 18 mm above the floor
    with warnings.catch_warnings():
        warnings.simplefilter("error", ContactMarginWarning)
        ImplicitEuler(model, 0.01).step(state)


def _pulled_cube(with_rigid: bool, **contact) -> Model:
    """The soft cube 0.5 mm above the floor with a cable along its top (pulled from x = -5),
    and with `with_rigid` a rigid box resting on it."""
    from pliant.constraints.base import EmbeddedPoints
    from pliant.constraints.cable import CableActuator
    from pliant.fem.rigid import RigidBody

    body = _cube(lift=0.5).body
    path = EmbeddedPoints(body.mesh, [[2.0, 2.0, 10.5], [10.0, 2.0, 10.5], [18.0, 2.0, 10.5]])
    cable = CableActuator(path, body.rest_positions, pull_point=[-5.0, 2.0, 10.5])
    rigid = (
        [RigidBody(Box([6.0, 6.0, 3.0], position=[10.0, 10.0, 22.5]), 0.002, friction=0.3)]
        if with_rigid
        else []
    )
    return Model(
        body,
        actuators=[cable],
        contacts=Contacts([Plane()], friction=0.5, margin=1.0, **contact),
        rigid_bodies=rigid,
    )


@pytest.mark.parametrize("with_rigid", [False, True])
def test_kept_point_compliance_gives_the_problem_of_solving_every_column(with_rigid) -> None:
    """The contact columns read from the points' compliance kept for a factorisation
    (pliant.solvers.compliance) give the W, delta_free and step of solving all columns at every
    step, to round-off: over a fall, a bounce and rest on the floor (contacts appear and go,
    the lagged factorisation is reused and renewed), with and without a rigid body on top."""
    model = _pulled_cube(with_rigid)
    kept = ImplicitEuler(model, 0.01, contact_screening=False)
    solved = ImplicitEuler(model, 0.01, point_compliance=False)
    state = model.rest_state()
    checked = 0
    for i in range(60):
        command = np.array([min(0.05 * i, 1.0)])
        new = kept.step(state, command)
        reference = solved.step(state, command)
        a, b = kept.last_report.problem, solved.last_report.problem
        assert a.slices == b.slices
        if a.slices["contact"].stop > a.slices["contact"].start:
            checked += 1
        scale = np.abs(b.compliance).max()
        assert np.abs(a.compliance - b.compliance).max() < 1e-9 * scale
        assert np.abs(a.free_distance - b.free_distance).max() < 1e-9
        assert np.abs(new.positions - reference.positions).max() < 1e-7
        state = new
    assert checked > 30
    assert kept.system.factorisations > 1  # columns were renewed with the factorisation


@pytest.mark.parametrize("with_rigid", [False, True])
def test_contact_screening_gives_the_step_of_the_whole_contact_problem(with_rigid) -> None:
    """Screening solves only the contacts that may close and checks that the others stay open;
    from the same state, its step equals the step solving every contact within the margin to
    the contact tolerance, over a cube pulled by a cable that falls, bounces and rests on the
    floor (a box on top with `with_rigid`). The contacts left out get zero force, and a
    second round takes back the contacts the first one would have closed."""
    model = _pulled_cube(with_rigid, tolerance=1e-8)
    screened = ImplicitEuler(model, 0.01)
    whole = ImplicitEuler(model, 0.01, contact_screening=False)
    state = model.rest_state()
    left_out, second_rounds = 0, 0
    for i in range(60):
        command = np.array([min(0.05 * i, 1.0)])
        new = screened.step(state, command)
        reference = whole.step(state, command)
        report = screened.last_report.contact
        if report is not None:
            left_out += report.screened
            second_rounds += report.rounds > 1
            assert len(new.contact_forces.keys) == len(reference.contact_forces.keys)
            np.testing.assert_allclose(
                new.contact_forces.forces, reference.contact_forces.forces, atol=1e-4
            )
        assert np.abs(new.positions - reference.positions).max() < 1e-6
        if with_rigid:
            assert np.abs(new.rigid_positions - reference.rigid_positions).max() < 1e-6
        state = new
    assert left_out > 100  # most contacts within the margin stay open
    assert second_rounds > 0


def test_object_effector_rows_predict_the_carried_object_exactly(monkeypatch) -> None:
    """A rigid box resting on a soft cube whose cable pulls: the rows of an effector on the box
    in the step's condensed problem, W_e lambda + delta_e_free (coupled to the contacts by
    h^2 J M^-1 G^T), equal the box's centre after the step, to round-off."""
    from dataclasses import dataclass

    from pliant.constraints.base import EmbeddedPoints
    from pliant.constraints.cable import CableActuator
    from pliant.constraints.control import DirectControl
    from pliant.constraints.effector import RigidEffector
    from pliant.fem.rigid import RigidBody
    from pliant.solvers import implicit_euler

    @dataclass
    class WithObjectRows(DirectControl):
        roles = ("actuator", "effector")  # the effector rows condensed, yet passive

    chosen = []
    forces = implicit_euler.constraint_forces

    def recorded(*args):
        out = forces(*args)
        chosen.append(out[0])
        return out

    monkeypatch.setattr(implicit_euler, "constraint_forces", recorded)
    body = _cube(lift=0.5).body
    path = EmbeddedPoints(body.mesh, [[2.0, 10.0, 18.0], [18.0, 10.0, 18.0]])
    cable = CableActuator(path, body.rest_positions, pull_point=[-5.0, 10.0, 18.0], mode="force")
    box = RigidBody(Box([4.0, 4.0, 2.0], position=[10.0, 10.0, 22.6]), 0.002, friction=0.8)
    goal = np.array([6.0, 9.0, 22.0])
    target = RigidEffector(box, goal=goal, weight=2.0)
    model = Model(
        body,
        actuators=[cable],
        effectors=[target],
        contacts=Contacts([Plane()], friction=0.5, margin=1.0),
        rigid_bodies=[box],
    )
    solver = ImplicitEuler(model, 0.01)
    state = model.rest_state()
    coupled = 0
    for i in range(60):
        new = solver.step(state, WithObjectRows(np.array([min(1.0 * i, 40.0)])))
        problem = solver.last_report.problem
        se, sc = problem.slices["effector"], problem.slices["contact"]
        predicted = problem.compliance[se] @ chosen[-1] + problem.free_distance[se]
        assert np.abs(predicted - 2.0 * (new.rigid_positions[0] - goal)).max() < 1e-9
        assert np.allclose(model.distances(new.positions)[model.n_actuators :], predicted)
        coupled += bool(np.any(problem.compliance[se, sc]))
        state = new
    assert coupled > 30  # the box rested on the cube: its rows were coupled to the contacts
    assert abs(state.rigid_positions[0, 0] - 10.0) > 0.01  # the pulled cube carried it


def test_inverse_control_of_a_walker_resting_with_friction_keeps_its_contacts_sticking():
    """The Multigait resting on the floor (45 contacts, friction 0.7), asked to stay where it
    is: the QPCC solves from the previous step's friction states (89 axes sticking, one
    sliding). ProxQP once called that QP primal infeasible at its first iteration (its
    default 1e-4 certificate on W ~ 1e-4 mm/N), and the step kept the previous actuation with
    a warning; frictionless, the same step always solved."""
    from pliant.constraints.base import EmbeddedPoints
    from pliant.errors import ContactConvergenceWarning
    from pliant.robots.multigait import multigait
    from pliant.transfer.proxy import with_effector

    robot = multigait(mesh_size=6.0)
    rest = robot.body.rest_positions
    tips = rest[np.argsort(rest[:, 2])[:4]] + [0.0, 0.0, 2.0]  # just above the feet
    model = with_effector(robot, EmbeddedPoints(robot.body.mesh, tips))
    solver = ImplicitEuler(model, dt=0.01)
    state = model.rest_state()
    for _ in range(20):
        state = solver.step(state, np.zeros(model.n_actuators))
    assert np.count_nonzero(state.contact_forces.forces.reshape(-1, 3)[:, 0] > 0) > 10
    goals = model.effectors[0].points.positions(state.positions)
    with warnings.catch_warnings():
        warnings.simplefilter("error", ContactConvergenceWarning)
        after = solver.step(state, InverseControl(goals=goals))
    moved = model.effectors[0].points.positions(after.positions) - goals
    assert np.abs(moved).max() < 0.05


def test_resting_points_do_not_collide() -> None:
    """Contacts.resting: the cube's points touching the floor give rows; marked resting,
    none."""
    model = _cube(lift=0.0)
    x = model.rest_state().positions
    assert model.contacts.constraint(x, 0.01) is not None
    model.contacts.resting = np.ones(model.contacts.n_colliding, dtype=bool)
    assert model.contacts.constraint(x, 0.01) is None
