"""The robots: closed-loop inverse control of the Diamond, every builder builds, steps and
renders, and bad parameters raise errors that name the cause."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pliant import robots
from pliant.constraints.control import InverseControl
from pliant.errors import (
    ConstraintError,
    DegenerateElementError,
    InvertedElementError,
    MaterialError,
    ModelError,
    PliantError,
    UnknownRobotError,
)
from pliant.mesh import TetMesh
from pliant.robots.diamond import circle
from pliant.scenario import track_goals
from pliant.solvers import ImplicitEuler, StaticSolver
from pliant.viz.model_view import RobotCamera

# Goals 10 mm around the axis, 7 mm below the rest effector (z = 125): inside the workspace
# the four 20 mm cables reach (SoftRobots' Diamond tracks 15 mm circles at z = 115).
DIAMOND_GOALS = circle(4, radius=10.0, height=118.0)
MAX_CABLE = 20.0


@pytest.fixture(scope="module")
def diamond():
    return robots.diamond()


@pytest.fixture(scope="module")
def meshes() -> dict[str, TetMesh | None]:
    """Each robot's default mesh, so that parameter checks skip the meshing (None for a rod)."""
    return {name: getattr(robots.build(name).body, "mesh", None) for name in robots.ROBOTS}


def test_diamond_tracks_goals_in_closed_loop(diamond) -> None:
    """Inverse QP every step (dt = 0.01) until the effector settles: measured final errors
    0.001-0.007 mm in 10-13 steps per goal; the tolerance leaves a factor 7."""
    model = diamond
    seen = []
    results, _ = track_goals(
        model,
        ImplicitEuler(model, 0.01),
        model.rest_state(),
        DIAMOND_GOALS,
        max_steps=60,
        on_step=lambda state, goal: seen.append((state.actuation.copy(), state.displacement)),
    )
    errors = [r.error for r in results]
    assert max(errors) < 0.05, errors
    assert all(r.steps < 60 for r in results), [r.steps for r in results]
    forces = np.array([a for a, _ in seen])
    shortening = np.array([d for _, d in seen])
    assert forces.min() >= 0.0
    # The course bound holds on each step's linearised problem; the state can exceed it by
    # the linearisation error of a step (see test_constraints), here at most 0.05 mm.
    assert shortening.max() <= MAX_CABLE + 0.05
    # The goals need every cable: each pulled at some point.
    assert np.all(forces.max(axis=0) > 0.0)


def test_static_inverse_reaches_a_goal(diamond) -> None:
    """The same InverseControl through the static solver (one solver interface): the QP is
    re-solved at every Newton iteration; at equilibrium the effector misses the goal only by
    the bias of the QP's regularisation (measured 0.048 mm)."""
    model = diamond
    goal = DIAMOND_GOALS[0]
    state = StaticSolver(model).step(model.rest_state(), InverseControl(goals=[goal[None]]))
    assert np.linalg.norm(model.effectors[0].position(state.positions)[0] - goal) < 0.1
    assert np.all(state.actuation >= 0.0)
    assert np.all(state.displacement <= MAX_CABLE + 1e-8)


@pytest.mark.parametrize("name", sorted(robots.ROBOTS))
def test_every_robot_builds_steps_and_renders(name) -> None:
    entry = robots.entry(name)
    model = robots.build(name)
    assert model.n_actuators > 0 or model.drivers  # actuated, or moved by a driven base
    if entry.trajectories:
        assert model.effectors
    demo = entry.demo_actuation(0.5)
    if not hasattr(demo, "prepare"):  # commands, or a control object (trunk_push's QPCC)
        assert demo.shape == (model.n_actuators,)
    for trajectory in entry.trajectories.values():
        goals = trajectory(5)
        assert goals.shape == (5, 3) and np.all(np.isfinite(goals))
    solver, state = ImplicitEuler(model, 0.01), model.rest_state()
    for _ in range(5):
        state = solver.step(state, entry.demo_actuation(state.time + 0.5))
    assert np.all(np.isfinite(state.positions))
    moved = np.abs(state.positions - model.body.rest_positions).max()
    assert moved > 0.01
    camera = RobotCamera(model, view=entry.view)
    image = camera.frame(state)
    assert image.ndim == 3 and image.shape[:2] == (480, 640)
    drawn = np.any(image != image[0, 0], axis=-1)
    assert 0.01 < drawn.mean() < 0.9
    assert not np.array_equal(image, camera.frame(model.rest_state()))


@pytest.mark.parametrize(
    "parameters",
    [
        {"young_modulus": 0.0},
        {"young_modulus": -5.0},
        {"young_modulus": math.nan},
        {"young_modulus": math.inf},
        {"poisson_ratio": 0.5},
        {"poisson_ratio": -0.1},
        {"poisson_ratio": math.nan},
        {"rayleigh_mass": -1.0},
    ],
)
@pytest.mark.parametrize("name", sorted(robots.ROBOTS))
def test_invalid_materials_raise(name, parameters, meshes) -> None:
    with pytest.raises(MaterialError):
        robots.build(name, mesh=meshes[name], **parameters)


@pytest.mark.parametrize(
    ("name", "parameters"),
    [
        ("finger", {"density": 0.0}),
        ("finger", {"density": -1.0}),
        ("pneunet", {"density": math.nan}),
        ("diamond", {"total_mass": 0.0}),
        ("trunk", {"total_mass": -0.1}),
    ],
)
def test_invalid_mass_raises(name, parameters, meshes) -> None:
    with pytest.raises(MaterialError):
        robots.build(name, mesh=meshes[name], **parameters)


@pytest.mark.parametrize(
    ("name", "parameters", "error"),
    [
        ("diamond", {"material": "rubber"}, ModelError),
        ("finger", {"mass": "heavy"}, ModelError),
        ("finger", {"gravity": (0.0, 0.0, math.nan)}, ModelError),
        ("diamond", {"cable_mode": "pull"}, ConstraintError),
        ("pneunet", {"cavity_mode": "vacuum"}, PliantError),
    ],
)
def test_invalid_options_raise_named_errors(name, parameters, error, meshes) -> None:
    with pytest.raises(error):
        robots.build(name, mesh=meshes[name], **parameters)


def test_unknown_robot_raises() -> None:
    with pytest.raises(UnknownRobotError, match=f"available: {', '.join(sorted(robots.ROBOTS))}"):
        robots.build("octopus")
    with pytest.raises(UnknownRobotError):
        robots.entry("")


def test_inverted_mesh_is_rejected(meshes) -> None:
    finger_mesh = meshes["finger"]
    tets = finger_mesh.tets.copy()
    tets[5] = tets[5][[1, 0, 2, 3]]
    bad = TetMesh(finger_mesh.points, tets, finger_mesh.surfaces, finger_mesh.landmarks)
    with pytest.raises(InvertedElementError):
        robots.build("finger", mesh=bad)


def test_degenerate_mesh_is_rejected(meshes) -> None:
    finger_mesh = meshes["finger"]
    points = finger_mesh.points.copy()
    a, b, c, d = finger_mesh.tets[5]
    points[d] = (points[a] + points[b] + points[c]) / 3.0  # flat element
    bad = TetMesh(points, finger_mesh.tets, finger_mesh.surfaces, finger_mesh.landmarks)
    with pytest.raises(DegenerateElementError):
        robots.build("finger", mesh=bad)


def test_stiff_flop_chamber_bends_the_module_away_from_it() -> None:
    """Pressure in pair j alone lengthens that side: by the module's symmetry about the pair's
    azimuthal plane the tip moves in that plane, away from the pair, -(cos, sin)(120 j deg),
    and rises. Measured at 30 kPa in module 0: 0.28 and 0.34 deg off that direction for pairs
    0 and 1. The hoop fibres make it bend more than the bare silicone (4.31 vs 1.57 mm, which
    also strays 2.5-5 deg: its coarse chambers balloon unevenly).
    """

    from pliant.robots.stiff_flop import stiff_flop

    model = stiff_flop()
    bare = stiff_flop(mesh=model.body.mesh, fibre_stiffness=0.0)
    from pliant.trajopt import ForceControl as control

    shifts = {}
    for name, m in (("fibres", model), ("bare", bare)):
        static = StaticSolver(m)
        rest = m.effectors[0].position(static.step(m.rest_state(), control(np.zeros(6))).positions)
        for j in (0, 1) if name == "fibres" else (0,):
            u = np.zeros(6)
            u[j] = 30.0  # kPa, module 0 (its bend carries the tip module with it)
            tip = m.effectors[0].position(static.step(m.rest_state(), control(u)).positions)
            shifts[name, j] = (tip - rest)[0]
    for j in (0, 1):
        a = 2 * math.pi * j / 3
        away = -np.array([math.cos(a), math.sin(a)])
        d = shifts["fibres", j]
        cosine = d[:2] @ away / np.linalg.norm(d[:2])
        assert cosine > math.cos(math.radians(3.0)), (j, d)
        assert d[2] > 0.0
    assert np.linalg.norm(shifts["fibres", 0][:2]) > 1.5 * np.linalg.norm(shifts["bare", 0][:2])


@pytest.mark.parametrize("name", ["stiff_flop", "lianford"])
def test_new_robots_inverse_control_reaches_a_reachable_goal(name) -> None:
    """A goal made by known actuation (pressures / motor torques) is reached by closed-loop
    inverse control from the rest equilibrium (measured 0.001 mm in 7 steps for the
    Stiff-Flop, 0.011 mm in 3 for the Lianford's servos)."""
    from pliant.trajopt import ForceControl

    model = robots.build(name)
    u = np.zeros(model.n_actuators)
    if name == "lianford":
        u[[0, 3]] = 1e4, -1e4  # mN mm
    else:
        u[[1, 4]] = 30.0  # kPa
    static = StaticSolver(model)
    goal = model.effectors[0].position(static.step(model.rest_state(), ForceControl(u)).positions)
    start = static.step(model.rest_state(), ForceControl(np.zeros_like(u)))
    assert np.linalg.norm(model.effectors[0].position(start.positions) - goal) > 3.0
    results, _ = track_goals(
        model, ImplicitEuler(model, 0.02), start, goal, max_steps=80, tolerance=0.01
    )
    assert results[0].error < 0.05, results[0]


def test_lianford_leg_is_a_bent_rod() -> None:
    """One Lianford leg (the builder's section, material and elements), clamped at its motor
    end, under an end moment M about the motor axis: the elastica is a circular arc of
    curvature k = M / EI, so the end rotates by kL and moves (1 - cos kL)/k across the leg
    and L - sin(kL)/k along it (exact for large rotations). Measured with the 6 elements:
    across to 1e-4, along 0.7 % short (the end turned by 0.66 rad)."""
    import inspect

    from pliant.constraints.joint import RotationActuator
    from pliant.fem.material import Material
    from pliant.fem.rod import RodBody, RodSection
    from pliant.model import Model
    from pliant.robots.lianford import leg_nodes, lianford
    from pliant.trajopt import ForceControl

    d = {k: p.default for k, p in inspect.signature(lianford).parameters.items()}
    points, _, _, axes = leg_nodes(1, d["elements"], d["base_radius"], d["top_radius"], d["height"])
    leg = points[1:]
    rod = RodBody(
        leg,
        RodSection.circle(d["leg_radius"]),
        Material(d["young_modulus"], d["poisson_ratio"]),
        density=d["density"],
        clamped=[0],
    )
    end = len(leg) - 1
    moment = RotationActuator(rod, end, axes[0], mode="force")
    model = Model(rod, actuators=[moment])
    torque = 2000.0  # mN mm: the end turns by 0.66 rad
    state = StaticSolver(model).step(model.rest_state(), ForceControl(np.array([torque])))
    length = np.linalg.norm(leg[-1] - leg[0])
    along = (leg[-1] - leg[0]) / length
    across = np.cross(axes[0], along)  # the way a positive turn about the axis swings the end
    ei = d["young_modulus"] * RodSection.circle(d["leg_radius"]).inertia[0]
    k = torque / ei
    moved = state.positions[end] - leg[-1]
    assert moved @ across == pytest.approx((1 - math.cos(k * length)) / k, rel=1e-3)
    assert moved @ along == pytest.approx(-(length - math.sin(k * length) / k), rel=1e-2)
