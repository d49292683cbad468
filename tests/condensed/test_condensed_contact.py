"""The condensed model with contacts (thesis §5.1.4) on the coarse Finger hanging down (gravity
along its axis): a dataset with contact rows, a network against the constant-W0 baseline, the
Jacobian of Eq. 5.10-5.11, the elimination of Eq. 5.12-5.13, force control of a button and
Algorithm 1 on a gripper with the exact matrices, a gripper dataset, and bad input."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

pytest.importorskip("torch")
pytest.importorskip("h5py")

import h5py  # noqa: E402

from pliant import robots  # noqa: E402
from pliant.condensed.collect import collect  # noqa: E402
from pliant.condensed.contact import ContactRobot  # noqa: E402
from pliant.condensed.dataset import CollectionPlan, Dataset, Split  # noqa: E402
from pliant.condensed.manipulation import (  # noqa: E402
    Grasp,
    ManipulationController,
    Pose,
    RigidObject,
    follow_object,
    object_problem,
)
from pliant.condensed.sampling import Box  # noqa: E402
from pliant.condensed.train import TrainConfig, evaluate, train_condensed  # noqa: E402
from pliant.constraints.condensed import CondensedProblem  # noqa: E402
from pliant.errors import DatasetError, LearnedModelError, ModelError  # noqa: E402
from pliant.geometry.rotation import exp_map  # noqa: E402

HANGING = {"gravity": [9810.0, 0.0, 0.0]}  # the Finger pointing down, as in the gripper
# Cable 0 closes the finger onto the button, cable 1 mostly slack; the contact points held up
# to 0.9 mm back from where the cables put them, along the push: pushes of up to ~0.15 N
# (further, the finger held at its tip nears buckling under the cables' compression).
PLAN = CollectionPlan(
    "finger",
    ((0.0, 1.0), (-0.5, 0.4)),
    48,
    robot_kwargs=HANGING,
    contacts="contact_points",
    object_bounds=((0.0, 0.0), (0.0, 0.0), (-0.2, 0.9)),
    chunk_size=12,
    seed=1,
    consistent_tangent=False,  # the thesis' W (CollectionPlan.consistent_tangent)
)


@pytest.fixture(scope="module")
def robot() -> ContactRobot:
    return ContactRobot(robots.build("finger", **HANGING), "contact_points", consistent=False)


@pytest.fixture(scope="module")
def dataset(tmp_path_factory) -> Dataset:
    return collect(PLAN, tmp_path_factory.mktemp("contact") / "finger.h5", workers=1)


def test_dataset_with_contact_rows_round_trips(dataset, robot, tmp_path) -> None:
    loaded = Dataset.load(dataset.save(tmp_path / "copy.h5"))
    assert loaded.plan == PLAN and loaded.layout == dataset.layout
    assert loaded.layout.contacts == (("contact_points", 9),)
    for name in ("train", "test"):
        for f in dataclasses.fields(Split):
            np.testing.assert_array_equal(
                getattr(loaded.split(name), f.name), getattr(dataset.split(name), f.name)
            )
    train = loaded.train
    assert train.converged.all() and train.delta_c.shape == (48, 9)
    assert train.command.shape == (48, 5)  # two cables, then the object's translation
    with h5py.File(tmp_path / "copy.h5") as f:
        meta = json.loads(f.attrs["metadata"])
    assert meta["plan"]["contacts"] == "contact_points"
    assert meta["plan"]["object_bounds"] == [[0.0, 0.0], [0.0, 0.0], [-0.2, 0.9]]
    # a plan written before contacts existed still reads
    old = {k: v for k, v in PLAN.to_dict().items() if k not in ("contacts", "object_bounds")}
    assert CollectionPlan.from_dict({**old, "sampling": "box"}).contacts == ""

    # W and delta_free of a sample are the exact ones at its reached (delta_a, delta_c),
    # imposed again from rest
    k = 3
    state = robot.solve(robot.rest(), train.delta_a[k], train.delta_c[k])
    np.testing.assert_allclose(robot.split(state.displacement)[1], train.delta_c[k], atol=1e-9)
    w, free = robot.layout.pack(robot.problem(state))
    np.testing.assert_allclose(w, train.w_triangle[k], rtol=1e-5, atol=1e-9)
    np.testing.assert_allclose(free, train.free_distance[k], rtol=1e-5, atol=1e-6)


def test_learned_finger_with_contacts_beats_the_constant_w0_baseline(dataset) -> None:
    config = TrainConfig(
        epochs=150, batch_size=16, learning_rate=2e-3, hidden=(64, 64), progress=False
    )
    learned, _ = train_condensed(dataset, config)
    assert learned.input_box.dim == 11  # delta_a (2) and delta_c (9), Eq. 5.2
    scores = evaluate(learned, dataset.test)
    assert scores["samples"] == 12
    assert scores["loss"] < 0.1 * scores["baseline_loss"], scores  # ~1e-3 of it when written


# ---------------------------------------------------------------------------------------------
# Eq. 5.10-5.13


def test_contact_jacobian_of_eq_5_11_matches_finite_differences() -> None:
    """x_c - x_c_prev = J_c (X - X_prev) (Eq. 5.10): J_c of Eq. 5.11 against central
    differences of the contact points of a turned cube, increments composed in the world
    frame; and along a guide, J_c times the guide."""
    rng = np.random.default_rng(2)
    cube = RigidObject(rng.normal(size=(9, 3)) * 10.0, center=[1.0, -2.0, 0.5])
    pose = Pose(np.array([1.3, -1.6, 0.9]), exp_map(np.array([0.2, -0.4, 0.3])))
    h = 1e-6
    columns = [
        (cube.positions(pose.displaced(h * e)) - cube.positions(pose.displaced(-h * e))).ravel()
        / (2 * h)
        for e in np.eye(6)
    ]
    np.testing.assert_allclose(cube.jacobian(pose), np.column_stack(columns), atol=1e-7)

    guide = np.linalg.qr(rng.normal(size=(6, 2)))[0]
    button = RigidObject(cube.points, center=cube.center, guide=guide)
    fd = [
        (button.positions(button.displaced(pose, h * e)) - button.positions(pose)).ravel() / h
        for e in np.eye(2)
    ]
    np.testing.assert_allclose(button.jacobian(pose), np.column_stack(fd), atol=1e-4)
    np.testing.assert_allclose(
        button.coordinates(button.displaced(button.reference, [0.3, -0.2])), [0.3, -0.2], atol=1e-12
    )


def test_object_problem_eliminates_contact_forces_and_pose_exactly(robot) -> None:
    """Eq. 5.12-5.13 on random condensed problems of the three gripper fingers: for any
    lambda_a, X = A lambda_a + B and lambda_c satisfy the fingers' condensed equations, the
    kinematics of Eq. 5.10 and the cube's equilibrium J_c^T lambda_c = T - K dq, and the
    actuator rows are delta_a = W_aa lambda_a + W_ac lambda_c + delta_a_free."""
    grasp = Grasp.gripper(robot)
    rng = np.random.default_rng(5)
    layout = robot.layout
    problems = []
    for _ in range(grasp.n_fingers):
        a = rng.normal(size=(layout.n_rows, layout.n_rows))
        problems.append(
            CondensedProblem(
                a @ a.T + np.eye(layout.n_rows), rng.normal(size=layout.n_rows), layout.slices
            )
        )
    obj = grasp.object
    pose = obj.reference.displaced(rng.normal(size=6) * 0.01)
    load, stiffness = rng.normal(size=6), np.diag(rng.random(6))
    held = object_problem(grasp, problems, pose, np.zeros(6), load, stiffness, np.ones(6))
    lam_a = rng.normal(size=6)
    dq = held.increment(lam_a)
    lam_c = held.contact_forces(lam_a)
    j = obj.jacobian(pose)
    reached = obj.positions(pose).ravel() + j @ dq
    for f, (place, problem) in enumerate(zip(grasp.placements, problems, strict=True)):
        rows = slice(9 * f, 9 * f + 9)
        local_force = (lam_c[rows].reshape(3, 3) @ place.rotation).ravel()  # R^T f
        a = slice(2 * f, 2 * f + 2)
        moved = (
            problem.block("contact", "actuator") @ lam_a[a]
            + problem.block("contact", "contact") @ local_force
            + problem.free("contact")
        )
        np.testing.assert_allclose(
            place.to_world(robot.reference + moved.reshape(3, 3)).ravel(), reached[rows], atol=1e-9
        )
        delta_a = (
            problem.block("actuator", "actuator") @ lam_a[a]
            + problem.block("actuator", "contact") @ local_force
            + problem.free("actuator")
        )
        np.testing.assert_allclose(held.actuator_displacements(lam_a)[a], delta_a, atol=1e-9)
    np.testing.assert_allclose(j.T @ lam_c, load - stiffness @ dq, atol=1e-9)
    w = held.problem.compliance
    np.testing.assert_allclose(w, w.T, atol=1e-12)


# ---------------------------------------------------------------------------------------------
# Control on the exact plant


def test_force_control_with_the_exact_w_reaches_the_requested_button_force(robot) -> None:
    """The button of the thesis' Fig. 5.8, on a spring: the QP on Eq. 5.13 (exact W, the
    spring folded in) asks for a push; the FEM finger with the cap stuck to its contact
    points settles on the spring. Requested and reached within 0.5 % after three steps."""
    stiffness = 50.0  # mN/mm
    button = Grasp.button(robot, stiffness=stiffness)
    controller = ManipulationController(button, robot, load="known", regularisation=1e-6)
    push = np.array([0.0, 0.0, -1.0])  # from the contact face outwards, cable 0's way
    requested = np.array([30.0, 80.0])  # mN
    goals = [
        button.object.reference.displaced(np.r_[push * f / stiffness, 0, 0, 0]) for f in requested
    ]
    trajectory = follow_object(button, controller, goals, iterations=3)
    travel = np.array([(p.center - button.object.center) @ push for p in trajectory.reached])
    np.testing.assert_allclose(stiffness * travel, requested, rtol=5e-3)
    # the FEM settled anew from rest on each command: its contact forces are the push,
    # -n . sum lambda_c (lambda_c on the finger)
    states, start = button.start()
    for force, command in zip(requested, trajectory.commands, strict=True):
        settled, _ = button.settle(states, start, command)
        lam_c = button.contact_forces(settled).reshape(-1, 3)
        assert abs(-push @ lam_c.sum(axis=0) - force) < 5e-3 * force
    assert np.all(trajectory.commands[:, 0, 0] > 0.0)  # cable 0 pulls


def test_exact_algorithm_1_moves_the_gripper_cube_to_a_goal(robot) -> None:
    """Algorithm 1 with the exact matrices on the exact plant: three fingers gripping a cube
    (cables preloaded) move it 1 mm sideways; the cube stays in equilibrium."""
    grasp = Grasp.gripper(robot)
    states, start = grasp.start()
    controller = ManipulationController(grasp, robot, course=Box([0.0, 0.0], [6.0, 6.0]))
    goal = start.displaced([1.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    pose = start
    for _ in range(3):
        commands = controller.step(states, pose, goal)
        states, pose = grasp.settle(states, pose, commands)
    assert np.linalg.norm(pose.center - goal.center) < 0.15, pose.center - goal.center
    # in equilibrium to the plant's tolerance (1e-5 mm and rad of change), the contact forces
    # being hundreds of mN
    lam_c = grasp.contact_forces(states)
    residual = grasp.residual(states, pose)
    assert np.abs(lam_c).max() > 100.0
    assert np.abs(residual[:3]).max() < 0.05 and np.abs(residual[3:]).max() < 1.0, residual
    # lambda_c of Algorithm 1 (Eq. 5.12, the last step's) is the plant's, to a few %
    assert np.abs(controller.contact_forces - lam_c).max() < 0.05 * np.abs(lam_c).max()


def test_gripper_dataset_holds_one_rigid_cube_per_sampled_pose(tmp_path) -> None:
    """Gripper sampling: three samples (fingers) per sampled cube pose, whose contact points,
    put back in the world, are the cube's reference points moved rigidly."""
    plan = dataclasses.replace(
        PLAN,
        actuator_bounds=((0.0, 6.0), (0.0, 6.0)),
        n_train=2,
        test_fraction=0.5,
        object_bounds=((-1.0, 1.0), (-1.0, 1.0), (-0.2, 0.2)),
        sampling="gripper",
    )
    data = collect(plan, tmp_path / "gripper.h5", workers=1)
    assert (len(data.train), len(data.test)) == (6, 3) and data.train.converged.all()
    finger = ContactRobot(robots.build("finger", **HANGING), "contact_points", consistent=False)
    grasp = Grasp.gripper(finger)
    reference = grasp.object.points
    for k in range(2):
        points = np.vstack(
            [
                place.to_world(grasp.robot.reference + data.train.delta_c[3 * k + f].reshape(3, 3))
                for f, place in enumerate(grasp.placements)
            ]
        )
        distances = np.linalg.norm(points[:, None] - points[None], axis=-1)
        np.testing.assert_allclose(
            distances, np.linalg.norm(reference[:, None] - reference[None], axis=-1), atol=1e-6
        )
        np.testing.assert_array_equal(
            data.train.command[3 * k, 2:], data.train.command[3 * k + 2, 2:]
        )


# ---------------------------------------------------------------------------------------------
# Bad input


def test_bad_contact_settings_raise_specific_errors(robot) -> None:
    with pytest.raises(DatasetError, match="name them with `contacts`"):
        dataclasses.replace(PLAN, contacts="")
    with pytest.raises(DatasetError, match="sampling must be one of"):
        dataclasses.replace(PLAN, sampling="grid")
    with pytest.raises(DatasetError, match="translation .3. or a translation and a rotation"):
        dataclasses.replace(PLAN, object_bounds=((0.0, 1.0),))
    with pytest.raises(DatasetError, match="needs `contacts` and `object_bounds`"):
        dataclasses.replace(PLAN, object_bounds=(), contacts="", sampling="gripper")
    finger = robots.build("finger")
    with pytest.raises(ModelError, match="no landmark 'tip_points'"):
        ContactRobot(finger, "tip_points")
    with pytest.raises(ModelError, match="no contact points"):
        Grasp.gripper(ContactRobot(finger))
    with pytest.raises(ModelError, match="orthonormal"):
        RigidObject(np.eye(3), guide=np.ones((6, 1)))
    with pytest.raises(ModelError, match="load must be"):
        ManipulationController(Grasp.button(robot, stiffness=1.0), robot, load="guessed")

    class OtherLayout:  # a model learned without the contact rows
        layout = dataclasses.replace(robot.layout, contacts=())

    with pytest.raises(LearnedModelError, match="contacts"):
        ManipulationController(Grasp.button(robot, stiffness=1.0), OtherLayout())
