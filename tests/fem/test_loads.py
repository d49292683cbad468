"""External loads and partial supports: closed-form answers, the cavity equivalence of a
pressure load, the follower load's tangent against finite differences, and the error a
body held too little raises in the static solve."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import distorted_box
from scipy.spatial.transform import Rotation

from pliant.constraints.base import EmbeddedPoints
from pliant.constraints.cable import CableActuator
from pliant.constraints.cavity import CavityActuator
from pliant.errors import ModelError
from pliant.fem.body import TetBody, fixed_components
from pliant.fem.loads import (
    FollowerForce,
    NodalForces,
    RestShapeSprings,
    RotationSprings,
    SurfacePressure,
    SurfaceTraction,
)
from pliant.fem.material import Corotational
from pliant.fem.supports import OnLine, OnPlane
from pliant.mesh import box_beam
from pliant.model import Model
from pliant.solvers import ImplicitEuler, StaticSolver

E, NU = 1000.0, 0.3


def _face(mesh, axis: int, value: float) -> np.ndarray:
    """Boundary triangles lying on the plane x[axis] = value (outward normals)."""
    tri = mesh.boundary_triangles()
    return tri[np.all(np.abs(mesh.points[tri][:, :, axis] - value) < 1e-9, axis=1)]


def _bar_supports(x: np.ndarray) -> np.ndarray:
    """Single components that hold a bar's rigid motions and nothing else: u_x = 0 on the
    x = 0 face, u_y = u_z = 0 at the origin, u_z = 0 at (0, b, 0)."""
    face = np.flatnonzero(np.abs(x[:, 0]) < 1e-9)
    origin = np.flatnonzero(np.linalg.norm(x, axis=1) < 1e-9)
    side = np.flatnonzero(np.linalg.norm(x - [0.0, x[:, 1].max(), 0.0], axis=1) < 1e-9)
    return np.concatenate(
        [
            fixed_components(face, (True, False, False)),
            fixed_components(origin, (False, True, True)),
            fixed_components(side, (False, False, True)),
        ]
    )


@pytest.mark.parametrize("stress", [1.0, 50.0])
def test_uniaxial_traction_gives_the_exact_strains(rng, stress) -> None:
    """A traction sigma on the x = L face of a bar held only against rigid motions: every
    element has the strain sigma/E along x and -nu sigma/E across, exactly (a uniform stress
    is an equilibrium of any linear-tetrahedron mesh, and the polar corotational law with a
    symmetric F is linear in F - I), up to a 5 % strain."""
    mesh = distorted_box(rng)
    x = mesh.points
    length = x[:, 0].max()
    traction = SurfaceTraction(_face(mesh, 0, length), x, [stress, 0.0, 0.0])
    body = TetBody(
        mesh, Corotational(E, NU), density=1e-6, fixed_dofs=_bar_supports(x), loads=[traction]
    )
    model = Model(body)
    assert body.free_rigid_motions() == []
    solved = StaticSolver(model).step(model.rest_state())
    u = solved.positions - x
    # Displacement gradient per element: sum_a u_a (x) g_a.
    grad = np.einsum("eai,eaj->eij", u[mesh.tets], body.grads)
    expected = np.diag([stress / E, -NU * stress / E, -NU * stress / E])
    assert np.abs(grad - expected).max() < 1e-9 * stress / E


def test_a_pressure_load_on_a_closed_surface_equals_the_cavity_actuator() -> None:
    """Pressure p on the whole (closed) boundary, pushing outwards, against a cavity
    actuator on the same surface in force mode at lambda = p: the forces are p dV/dx both
    ways, so the static equilibria agree to the solver's tolerance."""
    mesh = box_beam(10.0, 10.0, 10.0, 2, 2, 2)
    x = mesh.points
    clamp = np.flatnonzero(x[:, 0] < 1e-9)
    surface = mesh.boundary_triangles()
    pressure = 20.0
    loaded = TetBody(
        mesh,
        Corotational(E, NU),
        density=1e-6,
        fixed_nodes=clamp,
        loads=[SurfacePressure(surface, pressure)],
    )
    by_load = StaticSolver(Model(loaded)).step(Model(loaded).rest_state())
    body = TetBody(mesh, Corotational(E, NU), density=1e-6, fixed_nodes=clamp)
    cavity = CavityActuator(surface, x, mode="force", value=pressure, min_force=0.0)
    model = Model(body, actuators=[cavity])
    by_actuator = StaticSolver(model).step(model.rest_state())
    motion = np.abs(by_load.positions - x).max()
    assert motion > 0.1
    assert np.abs(by_load.positions - by_actuator.positions).max() < 1e-8 * motion


def test_the_follower_load_tangent_matches_force_differences(rng) -> None:
    """K = -df/dx of the pressure on an open surface (not symmetric) against central
    differences, and the body's assembled part (its symmetric part) on a closed one, where
    the full tangent is symmetric: K u = -(f(x + e u) - f(x - e u)) / 2e + O(e^2)."""
    mesh = box_beam(20.0, 10.0, 10.0, 2, 1, 1)
    x = mesh.points + 0.5 * rng.standard_normal(mesh.points.shape)
    for surface in (_face(mesh, 2, 10.0), mesh.boundary_triangles()):
        load = SurfacePressure(surface, 3.0)
        tangents = load.group_tangents(x, 0.0)
        u = rng.standard_normal(x.shape)
        eps = 1e-6
        fd = -(load.forces(x + eps * u, 0.0) - load.forces(x - eps * u, 0.0)) / (2 * eps)
        ku = np.zeros_like(x)
        np.add.at(
            ku,
            load.groups,
            np.einsum("trc,tc->tr", tangents, u[load.groups].reshape(-1, 9)).reshape(-1, 3, 3),
        )
        assert np.abs(ku - fd).max() < 1e-7 * np.abs(fd).max()
    body = TetBody(mesh, Corotational(E, NU), density=1e-6, loads=[load])
    lin = body.linearise(x)
    elastic = TetBody(mesh, Corotational(E, NU), density=1e-6).linearise(x)
    v = rng.standard_normal(body.n_free)
    assembled = body.stiffness_matvec(lin, v) - TetBody(
        mesh, Corotational(E, NU), density=1e-6
    ).stiffness_matvec(elastic, v)
    fd = -(load.forces(x + eps * v.reshape(-1, 3)) - load.forces(x - eps * v.reshape(-1, 3)))
    assert np.abs(assembled - fd.ravel() / (2 * eps)).max() < 1e-7 * np.abs(fd).max() / eps


@pytest.mark.parametrize("solver", ["static", "dynamic"])
def test_rest_shape_springs_hold_a_body_and_give_its_exact_offset(solver) -> None:
    """Springs k on every node and the same force f on every node: the body translates
    rigidly by f / k (no strain, so no elastic force), in the static solve and as the
    damped dynamics' steady state."""
    mesh = box_beam(20.0, 10.0, 10.0, 2, 1, 1)
    x = mesh.points
    nodes = np.arange(mesh.n_nodes)
    f, k = np.array([0.3, -0.2, 0.5]), 2.0
    body = TetBody(
        mesh,
        Corotational(E, NU),
        density=1e-6,
        rayleigh_mass=200.0,
        loads=[RestShapeSprings(nodes, x, k), NodalForces(nodes, f)],
    )
    model = Model(body)
    assert body.free_rigid_motions() == []
    if solver == "static":
        state = StaticSolver(model).step(model.rest_state())
    else:
        sim, state = ImplicitEuler(model, 0.01, tangent="fresh"), model.rest_state()
        for _ in range(40):
            state = sim.step(state)
    assert np.abs(state.positions - (x + f / k)).max() < 1e-9


def test_a_time_varying_load_follows_its_schedule() -> None:
    """A nodal force switched on at t = 0.05 s: nothing moves before (no gravity)."""
    mesh = box_beam(20.0, 10.0, 10.0, 2, 1, 1)
    x = mesh.points
    tip = np.flatnonzero(x[:, 0] > 20.0 - 1e-9)
    load = NodalForces(tip, [0.0, 0.0, -1.0], schedule=lambda t: float(t >= 0.05 - 1e-12))
    body = TetBody(
        mesh,
        Corotational(E, NU),
        density=1e-6,
        fixed_nodes=np.flatnonzero(x[:, 0] < 1e-9),
        loads=[load],
    )
    model = Model(body)
    sim, state = ImplicitEuler(model, 0.01, tangent="fresh"), model.rest_state()
    for _ in range(5):
        state = sim.step(state)
    assert np.abs(state.positions - x).max() == 0.0
    state = sim.step(state)
    assert (state.positions - x)[tip, 2].max() < 0.0


def test_a_body_held_too_little_names_its_free_rigid_motions() -> None:
    """Only the x components of the clamped face held: the body can slide along y and z and
    turn about x; held only by a cable, every rigid motion is free. The static solve refuses
    both with the motions named (it used to invert a singular stiffness)."""
    mesh = box_beam(30.0, 10.0, 10.0, 3, 1, 1)
    x = mesh.points
    face = np.flatnonzero(x[:, 0] < 1e-9)
    body = TetBody(
        mesh, Corotational(E, NU), density=1e-6, fixed_dofs=fixed_components(face, (1, 0, 0))
    )
    with pytest.raises(ModelError) as err:
        StaticSolver(Model(body))
    message = str(err.value)
    for motion in ("translation along (0, 1, 0)", "translation along (0, 0, 1)"):
        assert motion in message
    assert "rotation about the axis (1, 0, 0)" in message
    free = TetBody(mesh, Corotational(E, NU), density=1e-6, loads=[NodalForces([0], [0, 0, 1])])
    cable = CableActuator(
        EmbeddedPoints(mesh, np.array([[0.0, 5.0, 8.0], [30.0, 5.0, 8.0]])), x, value=1.0
    )
    with pytest.raises(ModelError, match="every rigid motion"):
        StaticSolver(Model(free, actuators=[cable]))


def _tip_model(projections, loads, **kwargs) -> Model:
    mesh = box_beam(30.0, 10.0, 10.0, 3, 1, 1)
    x = mesh.points
    body = TetBody(
        mesh,
        Corotational(E, NU),
        density=1e-6,
        fixed_nodes=np.flatnonzero(x[:, 0] < 1e-9),
        projections=projections,
        loads=loads,
        rayleigh_mass=20.0,
        **kwargs,
    )
    return Model(body)


def _solve(model: Model, solver: str):
    if solver == "static":
        return StaticSolver(model).step(model.rest_state())
    sim, state = ImplicitEuler(model, 0.01), model.rest_state()  # the default lagged tangent
    for _ in range(60):
        state = sim.step(state)
    return state


@pytest.mark.parametrize("solver", ["static", "dynamic"])
def test_nodes_on_an_inclined_plane_stay_on_it_and_slide_freely(solver) -> None:
    """The tip face held on the plane through it with normal (0, 1, 1)/sqrt 2, pulled down
    and sideways: the nodes stay on the plane to round-off (every increment is projected),
    they move along it, and at the static equilibrium the plane pushes only along its
    normal: the net force on each held node (elastic + load) is parallel to n."""
    mesh = box_beam(30.0, 10.0, 10.0, 3, 1, 1)
    tip = np.flatnonzero(mesh.points[:, 0] > 30.0 - 1e-9)
    n = np.array([0.0, 1.0, 1.0]) / np.sqrt(2.0)
    load = NodalForces(tip, [5.0, 10.0, -30.0])
    model = _tip_model([OnPlane(tip, n)], [load])
    state = _solve(model, solver)
    u = state.positions - model.body.rest_positions
    motion = np.abs(u[tip]).max()
    assert motion > 0.1
    assert np.abs(u[tip] @ n).max() < 1e-12 * motion
    if solver == "static":
        net = model.body.linearise(state.positions).forces[tip]
        along = net - np.outer(net @ n, n)
        assert np.abs(along).max() < 1e-8 * np.abs(net).max()


def test_a_node_on_a_line_stays_on_it_in_both_solvers() -> None:
    """The tip face held on lines along (1, 1, -1)/sqrt 3 through its nodes: the tip moves
    only along that direction, the same equilibrium in the static solve and as the damped
    dynamics' steady state."""
    mesh = box_beam(30.0, 10.0, 10.0, 3, 1, 1)
    tip = np.flatnonzero(mesh.points[:, 0] > 30.0 - 1e-9)
    d = np.array([1.0, 1.0, -1.0]) / np.sqrt(3.0)
    model = _tip_model([OnLine(tip, d)], [NodalForces(tip, [0.0, 20.0, -20.0])])
    static, dynamic = _solve(model, "static"), _solve(model, "dynamic")
    for state in (static, dynamic):
        u = (state.positions - model.body.rest_positions)[tip]
        across = u - np.outer(u @ d, d)
        assert np.abs(across).max() < 1e-12 * np.abs(u).max()
    assert (
        np.abs(static.positions - dynamic.positions).max()
        < 1e-3 * np.abs(static.positions - model.body.rest_positions).max()
    )


def test_a_plane_along_an_axis_is_the_held_component() -> None:
    """OnPlane with normal x is fixed_components(..., (True, False, False)): the same static
    equilibrium to the Newton tolerance."""
    mesh = box_beam(30.0, 10.0, 10.0, 3, 1, 1)
    tip = np.flatnonzero(mesh.points[:, 0] > 30.0 - 1e-9)
    load = NodalForces(tip, [5.0, 10.0, -30.0])
    projected = _solve(_tip_model([OnPlane(tip, [1.0, 0.0, 0.0])], [load]), "static")
    held = _solve(
        _tip_model([], [load], fixed_dofs=fixed_components(tip, (True, False, False))), "static"
    )
    assert np.abs(projected.positions - held.positions).max() < 1e-10


def test_a_body_held_only_by_planes_names_what_they_leave_free() -> None:
    """The x = 0 face on planes of normal (1, 1, 0)/sqrt 2: it can still slide along
    (1, -1, 0) and along z, and turn about the normal."""
    mesh = box_beam(30.0, 10.0, 10.0, 3, 1, 1)
    face = np.flatnonzero(mesh.points[:, 0] < 1e-9)
    body = TetBody(
        mesh, Corotational(E, NU), density=1e-6, projections=[OnPlane(face, [1.0, 1.0, 0.0])]
    )
    with pytest.raises(ModelError) as err:
        StaticSolver(Model(body))
    message = str(err.value)
    assert "translation along (0, 0, 1)" in message
    assert "rotation about the axis (0.707, 0.707, 0)" in message
    with pytest.raises(ModelError, match="two lines or planes"):
        TetBody(
            mesh,
            Corotational(E, NU),
            density=1e-6,
            projections=[OnPlane(face, [1.0, 0.0, 0.0]), OnLine(face[:1], [0.0, 1.0, 0.0])],
        )


# ---------------------------------------------------------------------------------------------
# A point force that turns with the body


def test_the_follower_point_force_turns_rigidly_and_its_tangent_matches_differences(rng) -> None:
    """A force at a point of a bar, given at rest: under a rigid motion x = R X + c the nodes
    of the element carrying it get w_a R f0 exactly; on a randomly deformed bar its tangent
    K = -df/dx (not symmetric) equals central differences, K u = -(f(x + e u) - f(x - e u)) /
    2e + O(e^2)."""
    from scipy.spatial.transform import Rotation

    mesh = box_beam(30.0, 10.0, 10.0, 3, 1, 1)
    f0 = np.array([1.0, -2.0, 3.0])
    load = FollowerForce(mesh, [27.0, 4.0, 6.0], f0)
    turn = Rotation.from_rotvec([0.4, -1.1, 0.7]).as_matrix()
    moved = mesh.points @ turn.T + [3.0, -1.0, 2.0]
    forces = load.forces(moved)
    nodes = load.groups[0]
    assert np.abs(forces[nodes] - np.outer(load.weights, turn @ f0)).max() < 1e-13
    assert np.abs(np.delete(forces, nodes, axis=0)).max() == 0.0
    x = mesh.points + 0.8 * rng.standard_normal(mesh.points.shape)
    tangent = load.group_tangents(x, 0.0)[0]
    assert np.abs(tangent - tangent.T).max() > 1e-3 * np.abs(tangent).max()  # a follower load
    for _ in range(3):
        u = rng.standard_normal(x.shape)
        eps = 1e-6
        fd = -(load.forces(x + eps * u) - load.forces(x - eps * u)) / (2 * eps)
        ku = (tangent @ u[nodes].ravel()).reshape(4, 3)
        assert np.abs(ku - fd[nodes]).max() < 1e-7 * np.abs(fd).max()


def test_a_follower_tip_force_bends_the_bar_further_than_the_dead_one() -> None:
    """A cantilever's tip force, across the bar at rest: followed (it turns with the tip, so
    it stays across the bent bar) it bends the bar further than the same dead force (which
    the bending turns partly along the bar), and it is no longer vertical at equilibrium; the
    static solve and the damped dynamics' steady state agree for both."""
    mesh = box_beam(60.0, 10.0, 10.0, 6, 1, 1)
    x = mesh.points
    f0 = np.array([0.0, 0.0, -800.0])
    follower = FollowerForce(mesh, [59.0, 5.0, 5.0], f0)
    dead = NodalForces(follower.groups[0], follower.weights[:, None] * f0)
    tip = follower.groups[0]
    drops = {}
    for load in (follower, dead):
        body = TetBody(
            mesh,
            Corotational(E, NU),
            density=1e-6,
            fixed_nodes=np.flatnonzero(x[:, 0] < 1e-9),
            loads=[load],
            rayleigh_mass=30.0,
        )
        model = Model(body)
        static = StaticSolver(model).step(model.rest_state())
        sim, state = ImplicitEuler(model, 0.01), model.rest_state()
        for _ in range(80):
            state = sim.step(state)
        drop = -(static.positions - x)[tip, 2].mean()
        assert np.abs(state.positions - static.positions).max() < 1e-4 * drop
        drops[load] = drop
        if load is follower:
            assert abs(load.direction(static.positions)[0]) > 0.1 * np.linalg.norm(f0)
    assert drops[dead] > 5.0 and drops[follower] > 1.03 * drops[dead]  # 14.37 vs 13.81 mm


def test_a_body_force_turns_with_a_rigid_body() -> None:
    """A box (principal axes along its edges) pushed by a force f along its own x at r = (0,
    L, 0): a torque r x f = -L f z about a principal axis, so w_j = j h tau / I_z exactly (the
    gyroscopic term vanishes), the angle theta_k = h sum_{j<=k} w_j, and the velocity sums the
    turned force, v_n = h/m sum_{k<n} R_z(theta_k) f (the free motion takes the force at the
    start of the step). Its tangent against differences of the wrench under small turns."""
    from scipy.spatial.transform import Rotation

    from pliant.fem.rigid import BodyForce, RigidBody
    from pliant.geometry.collision import Box
    from pliant.geometry.rotation import exp_map
    from pliant.solvers.rigid import RigidSolver, RigidWorld

    mass, half, f, arm = 2.0, np.array([3.0, 2.0, 1.0]), 5.0, 2.0
    push = BodyForce([0.0, arm, 0.0], [f, 0.0, 0.0])
    body = RigidBody(Box(half), mass, forces=[push])
    world = RigidWorld([body], gravity=(0.0, 0.0, 0.0))
    h, n = 0.01, 40
    solver, state = RigidSolver(world, h), world.initial_state()
    for _ in range(n):
        state = solver.step(state)
    inertia_z = body.inertia[2, 2]
    w = h * (-arm * f) / inertia_z * np.arange(1, n + 1)
    theta = np.concatenate([[0.0], h * np.cumsum(w)])[:n]
    turned = Rotation.from_rotvec(np.outer(theta, [0.0, 0.0, 1.0])).apply([f, 0.0, 0.0])
    expected = h / mass * turned.sum(axis=0)
    assert np.abs(state.velocities[0] - expected).max() < 1e-12 * np.abs(expected).max()
    assert abs(state.angular_velocities[0][2] - w[-1]) < 1e-12 * abs(w[-1])
    rotation = Rotation.from_rotvec([0.3, -0.2, 0.9]).as_matrix()
    eps = 1e-6
    for axis in np.eye(3):
        fd = -(
            push.wrench(exp_map(eps * axis) @ rotation)
            - push.wrench(exp_map(-eps * axis) @ rotation)
        ) / (2 * eps)
        assert np.abs(push.tangent(rotation) @ axis - fd).max() < 1e-8


def test_rotation_springs_turn_back_from_any_rest_rotation() -> None:
    """The moment is -k times the rotation vector of the turn from rest, in world axes,
    whatever the rest rotation (here 120 degrees about (1, 1, 1)): a turn of 0.1 about z from
    rest gives (0, 0, -0.1 k); at rest none; tangent k I."""
    rest = Rotation.from_rotvec(2 * np.pi / 3 * np.ones(3) / np.sqrt(3))
    k = 300.0
    springs = RotationSprings([1], np.vstack([np.zeros(3), rest.as_rotvec()]), k)
    turned = (Rotation.from_rotvec([0.0, 0.0, 0.1]) * rest).as_rotvec()
    x = np.vstack([np.zeros(3), turned])
    np.testing.assert_allclose(springs.group_forces(x, 0.0)[0, 0], [0.0, 0.0, -0.1 * k], atol=1e-9)
    at_rest = np.vstack([np.zeros(3), rest.as_rotvec()])
    np.testing.assert_allclose(springs.group_forces(at_rest, 0.0), 0.0, atol=1e-12)
    np.testing.assert_allclose(springs.group_tangents(x, 0.0)[0], k * np.eye(3))
    with pytest.raises(ModelError, match="stiffness"):
        RotationSprings([1], at_rest, 0.0)
