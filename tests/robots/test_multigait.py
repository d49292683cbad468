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

MESHES = Path(__file__).resolve().parents[3] / "shared" / "meshes"


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
    phase, amplitude = 0.4, np.array([20.0, 10.0, 10.0, 10.0, 10.0])  # centre, legs
    index = {name: i for i, name in enumerate(CHAMBERS)}
    order = [("rear_left", "rear_right"), ("centre",), ("front_left", "front_right")]
    levels = np.array(
        [demo_actuation((k + 0.5) * phase, amplitude=(20.0, 10.0), phase=phase) for k in range(6)]
    )
    levels /= amplitude
    for g, names in enumerate(order):
        for name in names:
            expected = [0.0] * 6
            expected[g] = 0.5  # inflating
            for k in range(g + 1, g + 3):
                expected[k] = 1.0
            expected[g + 3] = 0.5  # deflating
            np.testing.assert_allclose(levels[:, index[name]], expected)


def test_inflated_rear_legs_stay_on_the_floor(robot) -> None:
    """Air pumped into the rear chambers grows them by the commanded volume, at a positive
    pressure; gravity and the floor keep the body down."""
    solver = ImplicitEuler(robot, 0.01)
    state = robot.rest_state()
    growth = np.array([0.0, 0.0, 0.0, 30.0, 30.0])  # mm^3, 4 % of a leg's chambers
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # Gauss-Seidel at its sweep limit on the impact steps
        for _ in range(15):
            state = solver.step(state, growth)
    np.testing.assert_allclose(state.displacement[3:], growth[3:], rtol=1e-3)
    assert np.all(np.abs(state.displacement[:3]) < 1.0) and np.all(state.actuation[3:] > 0.0)
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


def _gait_cycle(model, amplitude: tuple[float, float], phases: int = 6) -> dict[str, float]:
    """x travel over `phases` phases of the gait (0.6 s each) of the centre of mass and of the
    underside's front and rear ends, and the highest chamber pressure."""
    solver = ImplicitEuler(model, 0.01)
    state = model.rest_state()
    underside = np.flatnonzero(model.body.rest_positions[:, 2] < 1e-9)

    def ends(x: np.ndarray) -> np.ndarray:
        return np.array([x[underside, 0].min(), x[underside, 0].max()])

    start_com, start_ends = centre_of_mass(model, state.positions)[0], ends(state.positions)
    pressure = 0.0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ContactConvergenceWarning)
        for _ in range(phases * 60):
            state = solver.step(state, demo_actuation(state.time, amplitude=amplitude))
            pressure = max(pressure, float(state.actuation.max()))
    front, rear = ends(state.positions) - start_ends
    com = float(centre_of_mass(model, state.positions)[0] - start_com)
    return {"com": com, "front": front, "rear": rear, "pressure": pressure}


def test_a_gait_cycle_walks_the_robot_away_from_the_legs_inflated_first(robot) -> None:
    """Thesis §3.4.1's gait with SofaGym's volume growths (scaled to these chambers): one
    cycle from rest moves the centre of mass 6.4 mm towards the front legs (-x), and both ends
    of the underside follow (experiments/reduction/multigait_gait.py: 6.2 mm per cycle after the
    first); the chambers stay below the 50 kPa limit. Without the paper membrane the robot went
    0.4 mm the wrong way. Without actuation it stays put."""
    walk = _gait_cycle(robot, (4900.0, 3300.0))
    assert walk["com"] < -4.0
    assert walk["front"] < -4.0 and walk["rear"] < -4.0
    assert walk["pressure"] < 45.0
    still = _gait_cycle(robot, (0.0, 0.0), phases=2)
    assert max(abs(still["com"]), abs(still["front"]), abs(still["rear"])) < 0.05
