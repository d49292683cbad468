"""The maze scenes of issue 3: SimpleMaze (a maze tilted directly) and the Tripod that carries
the maze on its soft body, both with a ball rolling in the maze; and the BoxUnion shape of the
maze. Each scene's demo is run once per module and checked at its milestones; the rolling ball
against its closed form."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from conftest import mechanical_energy
from typer.testing import CliRunner

from pliant.cli import app
from pliant.errors import ConstraintError, ContactError, ModelError
from pliant.fem.rigid import RigidBody
from pliant.geometry.collision import Box, BoxUnion, Sphere, TriangleMesh, collide
from pliant.geometry.inertia import box_inertia, box_union_inertia
from pliant.geometry.rotation import log_map
from pliant.model import Model, State
from pliant.robots import simple_maze, tripod
from pliant.robots.common import smooth_ramp
from pliant.robots.simple_maze import BALL, MAZE, ball_in_maze, corridor_width, maze_path
from pliant.solvers import ImplicitEuler
from pliant.viz.model_view import RobotCamera

G = 9810.0  # mm/s^2
DT = 0.01
# Steps of the demos (pliant.robots.simple_maze.DEMO_MOVES): before the first move, the ball at
# the far end of corridor 0, the end (the goal reached at about 3.1 s).
START, CORRIDOR_0, END = 10, 60, 330


@pytest.fixture(scope="module")
def tripod_mesh():
    return tripod.tripod_mesh()


@dataclass
class Run:
    model: Model
    states: dict[int, State]  # kept at the requested step numbers
    clearance: float  # the smallest gap between the ball and the maze over the run (mm)
    height: float  # the highest the ball's centre rose above the maze's floor (mm)


def _run(model: Model, demo, steps: int, keep: tuple[int, ...] = ()) -> Run:
    solver, state = ImplicitEuler(model, DT), model.rest_state()
    ball, maze = model.rigid_bodies[BALL].shape, model.rigid_bodies[MAZE].shape
    states, clearance, height = {}, np.inf, -np.inf
    for _ in range(steps):
        state = solver.step(state, demo(state.time))
        maze.set_pose(state.rigid_positions[MAZE], state.rigid_rotations[MAZE])
        gap = maze.signed_distance(state.rigid_positions[BALL][None]).gap[0] - ball.radius
        clearance = min(clearance, gap)
        height = max(height, ball_in_maze(model, state)[2])
        if state.step in keep:
            states[state.step] = state
    states[state.step] = state
    return Run(model, states, clearance, height)


@pytest.fixture(scope="module")
def demo_runs(tripod_mesh) -> dict[str, Run]:
    """The two demos, 3.3 s each."""
    return {
        "simple_maze": _run(
            simple_maze.simple_maze(), simple_maze.demo_actuation, END, (START, CORRIDOR_0)
        ),
        "tripod_maze": _run(
            tripod.tripod_maze(mesh=tripod_mesh), tripod.demo_actuation, END, (START, CORRIDOR_0)
        ),
    }


SCENES = ("simple_maze", "tripod_maze")


@pytest.mark.parametrize("scene", SCENES)
def test_tilted_maze_rolls_the_ball_downhill(scene, demo_runs) -> None:
    """The demo's first move tilts the maze down towards +y (for the tripod: servo 0, whose arm
    points along +y, lowered and the two others lifted): gravity in the maze's plane points to
    +y, and the ball has rolled more than 30 mm that way (in the maze's frame and in the world)
    along corridor 0, between the border at x = -28 and the first inner wall at x = -10.7."""
    run = demo_runs[scene]
    before, after = run.states[START], run.states[CORRIDOR_0]
    in_plane = after.rigid_rotations[MAZE].T @ [0.0, 0.0, -G]
    assert in_plane[1] > 0.1 * G and abs(in_plane[0]) < 0.2 * in_plane[1]
    ball, radius = ball_in_maze(run.model, after), run.model.rigid_bodies[BALL].shape.radius
    assert ball[1] - ball_in_maze(run.model, before)[1] > 30.0
    assert -28.0 + radius - 1e-3 < ball[0] < -28.0 + corridor_width(60.0, 3, 2.0) - radius
    assert after.rigid_positions[BALL, 1] - before.rigid_positions[BALL, 1] > 30.0
    if scene == "tripod_maze":
        np.testing.assert_allclose(tripod.demo_servo_angles(after.time), [-0.4, 0.2, 0.2])
    else:  # the maze follows the gimbal's plate: it is tilted directly
        _, plate = run.model.drivers[0].carrier.pose(after.time)
        assert np.linalg.norm(log_map(after.rigid_rotations[MAZE] @ plate.T)) < 2e-3


@pytest.mark.parametrize("scene", SCENES)
def test_demo_takes_the_ball_through_the_maze_without_leaving_it(scene, demo_runs) -> None:
    """3.3 s of the demo: the ball ends at the goal, the far end of the last corridor, having
    crossed the maze (more than 35 mm along x); it never goes through a wall or the floor nor
    leaves the floor by more than 1 mm (the walls are 8 mm high). The contacts are linearised
    over a step, so a maze turning at w misses its arc by about r (w h)^2 / 2 at r from its
    centre: the tripod's maze swings at up to 3.5 rad/s, and the ball sinks up to 0.017 mm
    into it (SimpleMaze 0.0035 mm); bouncing on the soft tripod, it rises up to 0.3 mm."""
    run = demo_runs[scene]
    model, state = run.model, run.states[END]
    ball = ball_in_maze(model, state)
    goal = maze_path(60.0, 3, 2.0)[-1]
    assert np.linalg.norm(ball[:2] - goal) < corridor_width(60.0, 3, 2.0) / 2, ball
    assert ball[0] - ball_in_maze(model, model.rest_state())[0] > 35.0
    radius = model.rigid_bodies[BALL].shape.radius
    assert run.clearance > -0.05, run.clearance
    assert run.height < radius + 1.0, run.height


@pytest.mark.parametrize("scene", SCENES)
def test_scene_renders_the_moving_maze(scene, demo_runs) -> None:
    run = demo_runs[scene]
    camera = RobotCamera(run.model)
    image = camera.frame(run.states[CORRIDOR_0])
    assert np.any(image != image[0, 0], axis=-1).mean() > 0.05
    assert not np.array_equal(image, camera.frame(run.model.rest_state()))


def test_ball_rolls_down_the_tilted_maze_at_five_sevenths_g_sin_theta() -> None:
    """Once the plate has tilted (0.1 s ramp to theta_x = -0.1), the maze rests on its pad and
    the ball rolls along +y without slipping (mu = 0.3 > 2/7 tan theta): in the maze's frame
    its acceleration is 5/7 of the in-plane gravity (rolling sphere, I = 2/5 m r^2). A
    quadratic fit over 0.15-0.35 s (the ball rolls 27 mm) matches it within 1 % (measured
    0.02 %); the ball stays in the middle of its corridor."""
    model = simple_maze.simple_maze(tilt=lambda t: (-0.1 * smooth_ramp(t, 0.0, 0.1), 0.0))
    solver, state = ImplicitEuler(model, DT), model.rest_state()
    times, ys, gravity, xs = [], [], [], []
    for _ in range(35):
        state = solver.step(state)
        ball = ball_in_maze(model, state)
        times.append(state.time)
        ys.append(ball[1])
        xs.append(ball[0])
        gravity.append((state.rigid_rotations[MAZE].T @ [0.0, 0.0, -G])[1])
    window = np.array(times) > 0.15
    acceleration = 2.0 * np.polyfit(np.array(times)[window], np.array(ys)[window], 2)[0]
    expected = 5.0 / 7.0 * np.mean(np.array(gravity)[window])
    assert expected > 0.0 and acceleration == pytest.approx(expected, rel=0.01)
    assert np.ptp(xs) < 0.5


@pytest.mark.parametrize("scene", SCENES)
def test_energy_never_grows_without_actuation(scene, tripod_mesh) -> None:
    """Commands held at zero from rest: the pad or tripod sags under the maze and the ball
    rolls to a corner; the total energy only falls, up to what the contact solver's tolerance
    allows (as tests/robots/test_driven_and_rigid_scenes.py)."""
    if scene == "simple_maze":
        model = simple_maze.simple_maze(tilt=lambda t: (0.0, 0.0))
    else:
        model = tripod.tripod_maze(mesh=tripod_mesh, servo_angles=lambda t: np.zeros(3))
    solver, state = ImplicitEuler(model, DT), model.rest_state()
    energies = [mechanical_energy(model, state)]
    for _ in range(40):
        state = solver.step(state)
        energies.append(mechanical_energy(model, state))
    mass = model.body.total_mass + sum(b.mass for b in model.rigid_bodies)
    allowance = 10 * mass * G * model.contacts.tolerance
    assert np.diff(energies).max() <= allowance, np.diff(energies).max()
    assert energies[-1] < energies[0]


def test_servo_angles_out_of_range_raise(tripod_mesh) -> None:
    with pytest.raises(ConstraintError, match=r"servo 0: angle 1.6 rad .* \[-1.5, 1.5\]"):
        tripod.tripod_maze(mesh=tripod_mesh, servo_angles=lambda t: [1.6, 0.0, 0.0])
    with pytest.raises(ConstraintError, match="expected 3 angles"):
        tripod.tripod_maze(mesh=tripod_mesh, servo_angles=lambda t: [0.0, 0.0])
    model = tripod.tripod_maze(
        mesh=tripod_mesh, servo_angles=lambda t: [0.0, 0.0, -2.0 if t > 0.025 else 0.0]
    )
    solver, state = ImplicitEuler(model, DT), model.rest_state()
    state = solver.step(solver.step(state))
    with pytest.raises(ConstraintError, match="servo 2: angle -2.0 rad at t=0.03"):
        solver.step(state)
    # A larger range accepts the same command.
    tripod.tripod_maze(
        mesh=tripod_mesh, max_servo_angle=2.0, servo_angles=lambda t: [0.0, 0.0, -2.0]
    )


def test_tilt_out_of_range_and_bad_mazes_raise(tripod_mesh) -> None:
    with pytest.raises(ConstraintError, match=r"tilt 1: angle 0.3 rad .* \[-0.2, 0.2\]"):
        simple_maze.simple_maze(tilt=lambda t: (0.0, 0.3))
    with pytest.raises(ModelError, match="must fit in a corridor"):
        simple_maze.simple_maze(ball_radius=9.0)
    with pytest.raises(ModelError, match="do not fit"):
        simple_maze.maze_boxes(corridors=30)
    with pytest.raises(ModelError, match="positive integer"):
        tripod.tripod_maze(mesh=tripod_mesh, corridors=2.5)
    with pytest.raises(ModelError, match="do not fit"):
        tripod.tripod_mesh(boss_radius=30.0)
    with pytest.raises(ModelError, match="landmarks"):
        tripod.tripod_maze(mesh=simple_maze.simple_maze().body.mesh)


def test_box_union_meets_a_ball_box_by_box() -> None:
    """A ball resting in the corner of a floor and a wall gets one contact with each, with the
    exact gaps and face normals, and distinct identities; a single closed mesh of the same
    surface would give one closest point only."""
    floor, wall = Box([10.0, 10.0, 1.0], [0.0, 0.0, -1.0]), Box([1.0, 10.0, 3.0], [9.0, 0.0, 3.0])
    union = BoxUnion([floor, wall], position=[1.0, 2.0, 3.0])
    ball = Sphere(2.0, position=[1.0 + 6.0, 2.0, 3.0 + 2.1])
    contacts = collide(ball, union, margin=0.5)
    assert len(contacts) == 2
    np.testing.assert_allclose(np.sort(contacts.gap), [0.0, 0.1], atol=1e-12)
    normals = contacts.normal[np.argsort(contacts.gap)]
    np.testing.assert_allclose(normals, [[-1.0, 0.0, 0.0], [0.0, 0.0, 1.0]], atol=1e-12)
    assert len({tuple(k) for k in contacts.keys.tolist()}) == 2
    swapped = collide(union, ball, margin=0.5)
    np.testing.assert_allclose(np.sort(swapped.gap), [0.0, 0.1], atol=1e-12)
    surface = TriangleMesh(union.vertices, union.faces, position=[1.0, 2.0, 3.0])
    assert len(collide(ball, surface, margin=0.5)) == 1


def test_box_union_distance_and_mass_properties(rng) -> None:
    """Outside the boxes the union's distance is the one of its closed triangle surface (an
    independent computation, the mesh's BVH); two half boxes have the mass properties of the
    whole box; a rigid body needs the union centred on its centroid."""
    boxes = simple_maze.maze_boxes()
    union = BoxUnion(boxes, cell=5.0)
    surface = TriangleMesh(union.vertices, union.faces)
    points = rng.uniform(-40.0, 40.0, size=(400, 3))
    outside = union.signed_distance(points).gap > 1e-9
    assert outside.sum() > 200
    np.testing.assert_allclose(
        union.signed_distance(points[outside]).gap,
        surface.signed_distance(points[outside]).gap,
        atol=1e-9,
    )
    assert union.volume == pytest.approx(sum(8 * np.prod(b.half_extents) for b in boxes))
    halves = BoxUnion(
        [Box([1.0, 2.0, 3.0], [-1.0, 0.0, 0.0]), Box([1.0, 2.0, 3.0], [1.0, 0.0, 0.0])]
    )
    np.testing.assert_allclose(halves.centroid, 0.0, atol=1e-15)
    np.testing.assert_allclose(
        box_union_inertia(2.0, halves), box_inertia(2.0, [2.0, 2.0, 3.0]), rtol=1e-12
    )
    body = RigidBody(halves, 2.0)
    np.testing.assert_allclose(body.inertia, box_inertia(2.0, [2.0, 2.0, 3.0]), rtol=1e-12)
    with pytest.raises(ModelError, match="centre of mass"):
        RigidBody(BoxUnion([Box([1.0, 1.0, 1.0], [5.0, 0.0, 0.0])]), 1.0)
    with pytest.raises(ContactError, match="Box shapes"):
        BoxUnion([Sphere(1.0)])


def test_pliant_run_renders_the_simple_maze(tmp_path) -> None:
    result = CliRunner().invoke(
        app, ["run", "simple_maze", "--duration", "0.05", "--frames", "2", "--out", str(tmp_path)]
    )
    assert result.exit_code == 0, result.output
    assert (tmp_path / "simple_maze" / "simple_maze.gif").stat().st_size > 0


REFERENCE_TRIPOD = (
    Path(__file__).parents[3] / "shared" / "meshes" / "Maze_tripod_coarse_04_test.vtk"
)


@pytest.mark.skipif(not REFERENCE_TRIPOD.is_file(), reason="no reference meshes here")
def test_reference_tripod_mesh_carries_the_maze() -> None:
    """SofaGym's tripod mesh, turned z up: its three arm ends are clamped alike, and the demo's
    first move rolls the ball along corridor 0 as on Pliant's own tripod."""
    mesh = tripod.reference_tripod_mesh(REFERENCE_TRIPOD)
    assert mesh.n_tets == 2650 and mesh.points[:, 2].min() == 0.0
    run = _run(tripod.tripod_maze(mesh=mesh), tripod.demo_actuation, CORRIDOR_0, (START,))
    assert len({len(d.nodes) for d in run.model.drivers}) == 1
    moved = ball_in_maze(run.model, run.states[CORRIDOR_0]) - ball_in_maze(
        run.model, run.states[START]
    )
    assert moved[1] > 30.0, moved
