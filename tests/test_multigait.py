"""The Multigait quadruped: chambers, gait schedule, a few steps on the floor, a gait cycle."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

from pliant.constraints.cavity import enclosed_volume
from pliant.errors import ContactConvergenceWarning
from pliant.mesh.multigait import CHAMBERS, multigait_chambers, reference_cavity_surfaces
from pliant.robots.multigait import centre_of_mass, demo_actuation, multigait
from pliant.solvers import ImplicitEuler

MESHES = Path(__file__).resolve().parents[2] / "shared" / "meshes"


@pytest.fixture(scope="module")
def robot():
    return multigait()


def test_chambers_are_the_designed_slots(robot) -> None:
    """Each chamber's walls enclose exactly its slots (flat walls are meshed exactly)."""
    slots = multigait_chambers()
    for actuator, name in zip(robot.actuators, CHAMBERS, strict=True):
        volume = sum(float(np.prod(hi - lo)) for lo, hi in slots[name])
        assert actuator.rest_volume == pytest.approx(volume, rel=1e-9)


def test_gait_inflates_rear_centre_front_then_deflates_in_that_order() -> None:
    """Thesis §3.4.1, sampled at the middle of each of the six phases."""
    phase, p = 0.4, 10.0
    index = {name: i for i, name in enumerate(CHAMBERS)}
    order = [("rear_left", "rear_right"), ("centre",), ("front_left", "front_right")]
    levels = (
        np.array([demo_actuation((k + 0.5) * phase, pressure=p, phase=phase) for k in range(6)]) / p
    )
    for g, names in enumerate(order):
        for name in names:
            expected = [0.0] * 6
            expected[g] = 0.5  # inflating
            for k in range(g + 1, g + 3):
                expected[k] = 1.0
            expected[g + 3] = 0.5  # deflating
            np.testing.assert_allclose(levels[:, index[name]], expected)


def test_inflated_rear_legs_stay_on_the_floor(robot) -> None:
    """Pressure in the rear chambers grows them; gravity and the floor keep the body down."""
    solver = ImplicitEuler(robot, 0.01)
    state = robot.rest_state()
    pressure = np.array([0.0, 0.0, 0.0, 3.0, 3.0])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # Gauss-Seidel at its sweep limit on the impact steps
        for _ in range(15):
            state = solver.step(state, pressure)
    growth = state.displacement / np.array([a.rest_volume for a in robot.actuators])
    assert np.all(growth[3:] > 0.02) and np.all(np.abs(growth[:3]) < 0.005)
    # The collision points (a coarse subset of the underside, like the SOFA scene's collision
    # surface) stay on the floor; the nodes between them may sag slightly.
    assert robot.contacts.points.positions(state.positions)[:, 2].min() > -1e-4
    assert len(state.contact_forces.keys) > 0
    weight = robot.body.total_mass * 9810.0
    assert state.contact_forces.forces[:, 2].sum() == pytest.approx(weight, rel=0.5)


@pytest.mark.skipif(not MESHES.is_dir(), reason="reference meshes not available")
def test_reference_mesh_chamber_walls_are_found_from_the_scene_surfaces() -> None:
    import meshio

    from pliant.mesh import load_mesh

    mesh = load_mesh(MESHES / "MultiGaitRobot_full_quadriped_fine.vtk")
    files = {"centre": "Center", "rear_left": "Rear-Left"}
    surfaces = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # meshio's STL size heuristic overflows
        for name, stem in files.items():
            stl = meshio.read(MESHES / f"MultiGaitRobot_quadriped_{stem}-cavity_finer.stl")
            surfaces[name] = (stl.points, stl.cells_dict["triangle"])
    walls = reference_cavity_surfaces(mesh, surfaces)
    for name, triangles in walls.items():
        vertices, faces = surfaces[name]
        # The walls enclose the scene's cavity volume (both are closed, outward-oriented).
        expected = abs(enclosed_volume(vertices, faces))
        assert enclosed_volume(mesh.points, triangles) == pytest.approx(expected, rel=0.02)


def _gait_cycle(model, pressure: float) -> tuple[float, float]:
    """x travel of the centre of mass over one gait cycle at `pressure` (the default phase),
    and the largest volume growth of a chamber over the cycle, relative to its rest volume."""
    solver = ImplicitEuler(model, 0.01)
    state = model.rest_state()
    start = centre_of_mass(model, state.positions)[0]
    rest = np.array([a.rest_volume for a in model.actuators])
    growth = 0.0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ContactConvergenceWarning)
        for _ in range(6 * 60):  # six phases of 0.6 s
            state = solver.step(state, demo_actuation(state.time, pressure=pressure))
            growth = max(growth, float(np.max(state.displacement / rest)))
    return float(centre_of_mass(model, state.positions)[0] - start), growth


def test_a_gait_cycle_moves_the_robot_towards_the_legs_inflated_first(robot) -> None:
    """Thesis §3.4.1's gait at 30 kPa: 0.46 mm along +x on the first cycle (0.42 mm on the
    next ones, experiments/multigait_gait.py), the chambers at most 1.8 times their rest
    volume (at 35 kPa the centre balloons without bound); at zero pressure the robot stays
    put. The direction is the opposite of SofaGym's (see pliant.robots.multigait)."""
    travel, growth = _gait_cycle(robot, 30.0)
    assert travel > 0.25
    assert growth < 2.5
    assert abs(_gait_cycle(robot, 0.0)[0]) < 0.05
