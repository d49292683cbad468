"""Builders shared by the verification tests: small clamped beams and seeded randomness."""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import numba
import numpy as np
import pytest
from scipy.spatial import ConvexHull

from pliant.constraints.base import EmbeddedPoints
from pliant.constraints.cable import CableActuator
from pliant.fem.body import TetBody
from pliant.fem.material import Corotational, Material, NeoHookean
from pliant.fem.rod import RodBody, RodSection
from pliant.mesh import TetMesh, box_beam
from pliant.model import Model, State

MATERIALS: dict[str, type[Material]] = {"corotational": Corotational, "neo-hookean": NeoHookean}


def pytest_configure(config) -> None:
    """Under pytest-xdist (the README's test command runs one worker per core), each worker
    takes its share of the cores for numba's and PyTorch's thread pools, so that two workers
    on two cores do not run four busy threads."""
    workers = int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "1"))
    if workers > 1:
        share = max(1, (os.cpu_count() or 1) // workers)
        numba.set_num_threads(min(share, numba.config.NUMBA_NUM_THREADS))
        if importlib.util.find_spec("torch") is not None:
            import torch

            torch.set_num_threads(share)


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(20261123)


def clamped_body(
    mesh: TetMesh,
    material: Material,
    *,
    density: float = 1e-6,
    gravity: tuple[float, float, float] = (0.0, 0.0, 0.0),
    **kwargs,
) -> TetBody:
    """A body of `mesh` held at its x = min face (a cantilever's clamp)."""
    x = mesh.points
    fixed = np.flatnonzero(x[:, 0] <= x[:, 0].min() + 1e-9)
    return TetBody(mesh, material, density=density, fixed_nodes=fixed, gravity=gravity, **kwargs)


@pytest.fixture
def clamped_beam() -> Callable[..., Model]:
    """Factory: clamped_beam(material, size=(L, b, h), cells=(nx, ny, nz), actuators=..., ...)."""

    def build(
        material: Material,
        *,
        size: tuple[float, float, float] = (60.0, 20.0, 20.0),
        cells: tuple[int, int, int] = (6, 2, 2),
        actuators=(),
        effectors=(),
        **body_kwargs,
    ) -> Model:
        mesh = box_beam(*size, *cells)
        body = clamped_body(mesh, material, **body_kwargs)
        return Model(body, actuators=list(actuators), effectors=list(effectors), name="beam")

    return build


def distorted_box(rng: np.random.Generator, cells: int = 3, size: float = 30.0) -> TetMesh:
    """A cube of cells^3 Kuhn cells whose interior nodes are moved randomly by up to 30 % of
    a cell (a patch test needs an irregular mesh); returns the mesh, all volumes positive."""
    base = box_beam(size, size, size, cells, cells, cells)
    boundary = np.unique(base.boundary_triangles())
    interior = np.setdiff1d(np.arange(base.n_nodes), boundary)
    points = base.points.copy()
    h = size / cells
    points[interior] += rng.uniform(-0.3 * h, 0.3 * h, (interior.size, 3))
    mesh = TetMesh(points, base.tets)
    assert mesh.signed_volumes().min() > 0.0
    return mesh


@pytest.fixture
def distorted_mesh(rng) -> TetMesh:
    return distorted_box(rng)


def two_cable_beam(*, max_displacement: float = 1.0, effector_goal=None, **model_kwargs) -> Model:
    """A clamped 60 x 10 x 10 mm beam (E = 100 kPa), cables along its top (z = 8, cable 0) and
    bottom (z = 2) edges pulled from x = -10, a tip effector at (60, 5, 5)."""
    from pliant.constraints.base import EmbeddedPoints
    from pliant.constraints.cable import CableActuator
    from pliant.constraints.effector import PositionEffector

    mesh = box_beam(60.0, 10.0, 10.0, 12, 2, 2)
    x = mesh.points
    cables = [
        CableActuator(
            EmbeddedPoints(mesh, [[20.0, 5.0, z], [40.0, 5.0, z], [59.0, 5.0, z]]),
            x,
            pull_point=[-10.0, 5.0, z],
            name=f"cable_{i}",
            max_displacement=max_displacement,
        )
        for i, z in enumerate((8.0, 2.0))
    ]
    eff = PositionEffector(EmbeddedPoints(mesh, [[60.0, 5.0, 5.0]]), x, goals=effector_goal)
    body = clamped_body(mesh, Corotational(100.0, 0.3), density=1e-6)
    return Model(body, actuators=cables, effectors=[eff], **model_kwargs)


# A clamped rod along +x (tests/fem/test_rod.py, tests/constraints/test_attachment.py).
ROD_L, ROD_E, ROD_RADIUS = 100.0, 1000.0, 1.0  # mm, kPa, mm


def ball_surface(n: int, radius: float, centre=(0.0, 0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
    """A closed triangulated sphere: the convex hull of n Fibonacci points, faces outwards."""
    k = np.arange(n) + 0.5
    polar, turn = np.arccos(1.0 - 2.0 * k / n), np.pi * (1.0 + 5.0**0.5) * k
    unit = np.c_[np.cos(turn) * np.sin(polar), np.sin(turn) * np.sin(polar), np.cos(polar)]
    points = radius * unit
    faces = ConvexHull(points).simplices.copy()
    tri = points[faces]
    normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    inward = np.einsum("ij,ij->i", normals, tri.mean(axis=1)) < 0.0
    faces[inward] = faces[inward][:, ::-1]
    return points + np.asarray(centre, dtype=float), faces


def straight_rod(n: int, *, nu: float = 0.3, **kwargs) -> RodBody:
    """n elements along +x from the origin, clamped at x = 0."""
    points = np.column_stack([np.linspace(0.0, ROD_L, n + 1), np.zeros(n + 1), np.zeros(n + 1)])
    kwargs.setdefault("density", 1e-6)
    kwargs.setdefault("clamped", [0])
    return RodBody(points, RodSection.circle(ROD_RADIUS), Material(ROD_E, nu), **kwargs)


def dead_load(rod: RodBody, node: int, direction) -> CableActuator:
    """A constant force on a node in force mode: a cable pulled from 1e6 mm away along
    `direction` (its direction turns by at most the node's motion / 1e6)."""
    x = rod.rest_positions
    far = x[node] + 1e6 * np.asarray(direction, dtype=float)
    return CableActuator(
        EmbeddedPoints.at_nodes([node]), x, pull_point=far, mode="force", name=f"load_{node}"
    )


def mechanical_energy(model: Model, state: State) -> float:
    """Kinetic + gravitational + elastic energy of the body and of the rigid bodies."""
    body = model.body
    g = body.gravity
    total = 0.5 * float(np.sum(body.node_masses[:, None] * state.velocities**2))
    total -= float(np.sum(body.node_masses * (state.positions @ g)))
    total += body.linearise(state.positions).energy
    for i, b in enumerate(model.rigid_bodies):
        w = state.rigid_rotations[i].T @ state.rigid_angular_velocities[i]
        total += 0.5 * b.mass * float(state.rigid_velocities[i] @ state.rigid_velocities[i])
        total += 0.5 * float(w @ b.inertia @ w) - b.mass * float(g @ state.rigid_positions[i])
    return total


def run_scene(scene, steps: int) -> State:
    """A loaded SOFA scene (pliant.sofa.SofaScene) stepped `steps` times from rest by its own
    solver (controllers and hooks around each step); the last state."""
    solver, state = scene.solver(), scene.model.rest_state()
    for _ in range(steps):
        state = solver.step(state)
    return state


# The tutorials (examples/tutorial_*.py) run in their quick settings, in two files so that
# neither is a long pole under pytest-xdist's --dist loadfile: the learning ones
# (tests/interface/test_tutorials_learning.py) and every other (test_tutorials_simulation.py).
EXAMPLES = Path(__file__).parents[1] / "examples"
LEARNING_TUTORIALS = frozenset(
    {"condensed", "environment", "graph", "planning", "proxy", "reduction", "training"}
)


def tutorials(learning: bool) -> list[Path]:
    """The tutorial scripts of one of the two groups, sorted."""
    return [
        p
        for p in sorted(EXAMPLES.glob("tutorial_*.py"))
        if (p.stem.removeprefix("tutorial_") in LEARNING_TUTORIALS) == learning
    ]


def run_tutorial(script: Path, tmp_path: Path) -> None:
    """Run one tutorial with this checkout's pliant in its quick settings; it must exit 0
    and write its figures."""
    path = os.pathsep.join([str(EXAMPLES.parent), os.environ.get("PYTHONPATH", "")])
    env = {
        **os.environ,
        "PYTHONPATH": path,
        "PLIANT_TUTORIAL_QUICK": "1",
        "PLIANT_TUTORIAL_OUT": str(tmp_path),
    }
    result = subprocess.run(
        [sys.executable, str(script)], cwd=EXAMPLES.parent, capture_output=True, text=True, env=env
    )
    assert result.returncode == 0, result.stderr[-3000:]
    assert any((tmp_path / "tutorials").iterdir())
