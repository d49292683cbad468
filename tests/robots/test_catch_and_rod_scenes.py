"""The scenes of issue 3 built on rigid bodies and driven bases: CatchTheObject (a pneumatic
gripper on a cart catches a falling ball) and RodManipulator (two cable fingers turn a rod on a
table). Each scene's scripted demo is run once per module and checked at its milestones."""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
import pytest

from pliant.errors import ContactConvergenceWarning, ModelError
from pliant.model import Model, State
from pliant.robots import catch_object, rod_manipulator, trunk_cup
from pliant.solvers import ImplicitEuler
from pliant.viz import save_png
from pliant.viz.model_view import RobotCamera

G = 9810.0  # mm/s^2
DT = 0.01


@dataclass
class Run:
    model: Model
    states: dict[int, State]  # kept at the requested step numbers


def _run(model: Model, demo, keep: tuple[int, ...]) -> Run:
    """The scripted demo from rest, keeping the states at the steps in `keep`."""
    solver, state = ImplicitEuler(model, DT), model.rest_state()
    states = {}
    with warnings.catch_warnings():
        # Pressing on the rod, the contact solver stops within 0.03 mm of its tolerance.
        warnings.simplefilter("ignore", ContactConvergenceWarning)
        for _ in range(max(keep)):
            state = solver.step(state, demo(state.time))
            if state.step in keep:
                states[state.step] = state
    return Run(model, states)


@pytest.fixture(scope="module")
def catch_run() -> Run:
    return _run(catch_object.catch_object(), catch_object.demo_actuation, (20, 30))


@pytest.fixture(scope="module")
def rod_run() -> Run:
    return _run(rod_manipulator.rod_manipulator(), rod_manipulator.demo_actuation, (20, 55))


@pytest.fixture(scope="module")
def cup_run() -> Run:
    return _run(trunk_cup.trunk_cup(), trunk_cup.demo_actuation, (20, 40))


@pytest.mark.parametrize("scene", ["catch_run", "rod_run", "cup_run"])
def test_scene_steps_and_renders(scene, request, tmp_path) -> None:
    """20 scripted steps move the body with its carrier and stay finite; a PNG is rendered."""
    run = request.getfixturevalue(scene)
    model, state = run.model, run.states[20]
    assert np.all(np.isfinite(state.positions)) and np.all(np.isfinite(state.rigid_positions))
    assert np.abs(state.positions - model.body.rest_positions).max() > 1.0
    for driver in model.drivers:
        assert np.array_equal(state.positions[driver.nodes], driver.positions(state.time))
    image = RobotCamera(model).frame(state)
    assert np.any(image != image[0, 0], axis=-1).mean() > 0.01
    assert save_png(image, tmp_path / f"{scene}.png").stat().st_size > 0


def test_caught_ball_rests_on_the_palm_and_weighs_on_it(catch_run) -> None:
    """The cart slid 20 mm under the ball, which fell 72 mm into the gripper: at 0.3 s it
    rests between the fingers on the palm, touching the body without entering it, and the
    body's contact forces carry its weight m g upwards."""
    model, state = catch_run.model, catch_run.states[30]
    ball = model.rigid_bodies[0]
    radius = ball.shape.radius
    cart_x = model.drivers[0].carrier.pose(state.time)[0][0]
    x, _, z = state.rigid_positions[0]
    assert abs(x - cart_x) < 15.0 - radius  # between the fingers' inner faces (opening 30 mm)
    assert z - radius < 8.0 + 0.5  # down on the palm, whose top is at z = 8
    ball.shape.set_pose(state.rigid_positions[0], state.rigid_rotations[0])
    gap = ball.shape.signed_distance(state.positions).gap
    assert -model.contacts.tolerance < gap.min() < 1e-3  # touching the body, not inside it
    assert np.abs(state.rigid_velocities[0]).max() < 1.0
    on_ball = state.contact_forces.keys[:, 1] == len(model.contacts.shapes)
    force = state.contact_forces.forces[on_ball].sum(axis=0)
    weight = ball.mass * G
    # The forces recorded act on the body; the ball gets the opposite (Newton's third law).
    assert abs(-force[2] - weight) < 0.01 * weight, (force, weight)


def test_fingers_turn_the_rod_about_the_vertical(rod_run) -> None:
    """Bent in opposite directions while pressing on the rod, the fingers turn it
    counter-clockwise by tens of degrees about its centre, which barely moves; the rod stays
    on the table, none of its corners below it beyond the contact tolerance."""
    model, state = rod_run.model, rod_run.states[55]
    turn = np.degrees(rod_manipulator.rod_angle(state.rigid_rotations[0]))
    assert 15.0 < turn < 60.0, turn
    assert np.linalg.norm(state.rigid_positions[0, :2]) < 2.0
    rod = model.rigid_bodies[0].shape
    rod.set_pose(state.rigid_positions[0], state.rigid_rotations[0])
    corners, _ = rod.samples()
    table = model.contacts.shapes[0].position[2]
    assert corners[:, 2].min() > table - 10 * model.contacts.tolerance


def test_trunk_hooks_the_cup_and_drags_it_back(cup_run) -> None:
    """Curled down over the cup's far wall, the trunk drags the cup back towards its base by
    more than 10 mm in 0.4 s (measured: 21 mm); no trunk point is inside the cup and no cup
    vertex below the floor by more than 1e-3 mm (the contact solver stops within 5e-3 mm)."""
    model, state = cup_run.model, cup_run.states[40]
    cup = model.rigid_bodies[0]
    start = cup.position
    assert start[2] - state.rigid_positions[0, 2] > 10.0
    cup.shape.set_pose(state.rigid_positions[0], state.rigid_rotations[0])
    points = model.contacts.points.positions(state.positions)
    assert cup.shape.signed_distance(points).gap.min() > -1e-3
    vertices, _ = cup.shape.samples()
    floor = model.contacts.shapes[0].position[1]
    assert vertices[:, 1].min() > floor - 1e-3


def test_catcher_mesh_rejects_chambers_that_do_not_fit() -> None:
    with pytest.raises(ModelError, match="do not fit"):
        catch_object.catcher_mesh(finger_thickness=5.0, spine_thickness=3.0, wall=2.0)
