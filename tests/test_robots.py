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
