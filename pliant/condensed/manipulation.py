"""Objects held by fixed contact points (thesis §5.1.4): Eq. 5.10-5.13, Algorithm 1, and the
exact plant they are checked on.

* :class:`RigidObject` is the held object: its contact points and the Jacobian J_c of Eq. 5.11
  linking their motion to its own (Eq. 5.10), optionally guided along a few directions (a
  button) and loaded by a known force and a spring.
* :class:`Grasp` places copies of one :class:`~pliant.condensed.contact.ContactRobot` around an
  object by rigid transforms (a Finger pushing a button, a gripper of three Fingers), one
  condensed model serving every finger. :meth:`Grasp.settle` is the exact plant: the object's
  quasi-static equilibrium on the FEM fingers for given actuator displacements.
* :func:`object_problem` eliminates the contact forces and the object's pose (Eq. 5.12-5.13)
  into a condensed problem whose effector is the object, X = A lambda_a + B, for the inverse
  QP; :class:`ManipulationController` is Algorithm 1 on it, with learned or exact matrices.
* :func:`grasp_chunk` samples the thesis' contact datasets: inverse control in the cube's
  displacement space.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, fields
from typing import Literal

import numpy as np
from scipy.linalg import block_diag

from pliant.condensed.contact import ContactRobot, failed_row, sample_row
from pliant.condensed.control import CondensedSource, within
from pliant.condensed.dataset import GRIPPER_FINGERS, CollectionPlan, Split
from pliant.condensed.sampling import Box
from pliant.constraints.condensed import CondensedProblem
from pliant.constraints.inverse import solve_inverse
from pliant.errors import DivergenceError, ModelError, SolverError
from pliant.geometry.rotation import exp_map, log_map, skew
from pliant.model import Model, State


@dataclass(frozen=True)
class Pose:
    """Where a rigid object is: its centre and its rotation from the reference orientation."""

    center: np.ndarray
    rotation: np.ndarray = field(default_factory=lambda: np.eye(3))

    def displaced(self, increment: np.ndarray) -> Pose:
        """The pose moved by (translation, small rotation vector in the world frame), the
        increment X - X_prev of Eq. 5.10."""
        increment = np.asarray(increment, dtype=float)
        return Pose(self.center + increment[:3], exp_map(increment[3:]) @ self.rotation)

    def minus(self, other: Pose) -> np.ndarray:
        """The increment that displaces `other` to this pose."""
        return np.concatenate(
            [self.center - other.center, log_map(self.rotation @ other.rotation.T)]
        )


@dataclass(frozen=True, eq=False)
class RigidObject:
    """A rigid object holding contact points (§5.1.4).

    Args:
        points: the contact points at the reference pose, (points, 3).
        center: the reference centre X (default: the points' centroid).
        guide: (6, m), the directions the object may move along (translation then rotation
            vector, orthonormal columns): its m coordinates q displace the reference pose by
            guide q; None: free in all six (a cube in a gripper); fewer for an object some
            turns of which its contact points do not hold (three points on a line).
        stiffness, load: the external generalised force on the object, known:
            T_ext(q) = load - stiffness q (a spring to the reference pose, a constant force).
    """

    points: np.ndarray
    center: np.ndarray | None = None
    guide: np.ndarray | None = None
    stiffness: np.ndarray | None = None
    load: np.ndarray | None = None

    def __post_init__(self) -> None:
        points = np.asarray(self.points, dtype=float).reshape(-1, 3)
        center = points.mean(axis=0) if self.center is None else np.asarray(self.center, float)
        guide = np.eye(6) if self.guide is None else np.asarray(self.guide, float).reshape(6, -1)
        if not np.allclose(guide.T @ guide, np.eye(guide.shape[1]), atol=1e-9):
            raise ModelError("the guide's columns must be orthonormal directions")
        m = guide.shape[1]
        stiffness = np.zeros((m, m)) if self.stiffness is None else np.atleast_2d(self.stiffness)
        load = np.zeros(m) if self.load is None else np.ravel(self.load).astype(float)
        if stiffness.shape != (m, m) or load.shape != (m,):
            raise ModelError(
                f"stiffness and load must be ({m}, {m}) and ({m},) for {m} coordinates, got"
                f" {stiffness.shape} and {load.shape}"
            )
        for name, value in (
            ("points", points),
            ("center", center),
            ("guide", guide),
            ("stiffness", stiffness),
            ("load", load),
        ):
            object.__setattr__(self, name, value)

    @property
    def n_coordinates(self) -> int:
        return self.guide.shape[1]

    @property
    def reference(self) -> Pose:
        return Pose(self.center.copy())

    @property
    def size(self) -> float:
        """Mean distance of the contact points to the centre: the length that weighs the
        rotations against the translations."""
        return float(np.linalg.norm(self.points - self.center, axis=1).mean())

    def positions(self, pose: Pose) -> np.ndarray:
        """The contact points at `pose`, (points, 3)."""
        return pose.center + (self.points - self.center) @ pose.rotation.T

    def jacobian(self, pose: Pose) -> np.ndarray:
        """J_c of Eq. 5.11 at `pose`, (3 points, m): rows [I, [C]x] of each point, C = X - x_c,
        times the guide."""
        c = pose.center - self.positions(pose)
        full = np.concatenate([np.hstack([np.eye(3), skew(ci)]) for ci in c])
        return full @ self.guide

    def coordinates(self, pose: Pose) -> np.ndarray:
        """q of `pose` along the guide, from the reference pose."""
        return self.guide.T @ pose.minus(self.reference)

    def displaced(self, pose: Pose, dq: np.ndarray) -> Pose:
        return pose.displaced(self.guide @ np.ravel(dq))

    def external_load(self, pose: Pose) -> np.ndarray:
        """T_ext at `pose`, the generalised force the surroundings apply on the object."""
        return self.load - self.stiffness @ self.coordinates(pose)


@dataclass(frozen=True)
class Placement:
    """Where a copy of the robot stands: world = rotation @ local + translation."""

    rotation: np.ndarray = field(default_factory=lambda: np.eye(3))
    translation: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def to_world(self, points: np.ndarray) -> np.ndarray:
        return np.asarray(points).reshape(-1, 3) @ self.rotation.T + self.translation

    def to_local(self, points: np.ndarray) -> np.ndarray:
        return (np.asarray(points).reshape(-1, 3) - self.translation) @ self.rotation

    def block(self, n_points: int) -> np.ndarray:
        """The rotation of n_points stacked 3-vectors, (3 n, 3 n)."""
        return np.kron(np.eye(n_points), self.rotation)


PRELOAD_STEP = 0.5  # largest change of the actuators' displacement per step of the preload


class Grasp:
    """Copies of one robot, placed by rigid transforms, holding a rigid object by their contact
    points (the contact points of the object share their locations, §5.1.4).

    The object's contact points are the fingers' at their rest equilibrium (`rest`, computed
    if not given); its guide and load are :class:`RigidObject`'s. `weights` weigh the object's
    coordinates in the control (default: 1 per mm of translation, the object's size per
    radian of rotation; zero for a coordinate left uncontrolled). `preload` is the displacement
    of every actuator at the start, where the fingers grip (a cable can only pull: gripping
    leaves the control room both ways). The fingers share the robot (its model and solver);
    each has its own state.
    """

    def __init__(
        self,
        robot: ContactRobot,
        placements: Sequence[Placement],
        *,
        guide: np.ndarray | None = None,
        stiffness: np.ndarray | None = None,
        load: np.ndarray | None = None,
        weights: np.ndarray | None = None,
        rest: State | None = None,
        preload: float = 0.0,
    ) -> None:
        if robot.contact is None:
            raise ModelError(f"{robot.model.name} has no contact points to hold an object with")
        if not placements:
            raise ModelError("a grasp needs at least one finger (placement)")
        self.robot = robot
        self.placements = list(placements)
        self.rest_state = robot.rest() if rest is None else rest
        points = robot.contact_positions(self.rest_state)
        self.object = RigidObject(
            np.vstack([p.to_world(points) for p in self.placements]),
            guide=guide,
            stiffness=stiffness,
            load=load,
        )
        # per finger, the rotation of its stacked contact rows into the world
        self.rotations = [p.block(len(points)) for p in self.placements]
        obj = self.object
        if weights is None:
            # 1 per mm of translation, the object's size per radian of rotation
            per_axis = np.array([1.0, 1.0, 1.0, obj.size, obj.size, obj.size])
            weights = np.sqrt((obj.guide**2).T @ per_axis**2)
        self.weights = np.asarray(weights, dtype=float)
        self.preload = float(preload)
        self._start: tuple[list[State], Pose] | None = None

    @classmethod
    def gripper(
        cls,
        robot: ContactRobot,
        *,
        radius: float = 15.0,
        fingers: int = GRIPPER_FINGERS,
        preload: float = 1.5,
    ) -> Grasp:
        """Fingers hanging down around a free cube (local x along -z), their contact faces
        (local -z, the side cable 0 bends towards) turned to the vertical axis at `radius`,
        evenly spread: rotations about the vertical axis, so that gravity along -z is along
        +x for every finger and one condensed model (gravity (9810, 0, 0)) serves them all.
        The cables start at `preload` (mm): the fingers grip the cube."""
        placements = []
        for k in range(fingers):
            angle = 2.0 * math.pi * k / fingers
            out = np.array([math.cos(angle), math.sin(angle), 0.0])
            tangent = np.array([-math.sin(angle), math.cos(angle), 0.0])
            rotation = np.column_stack([[0.0, 0.0, -1.0], tangent, out])
            placements.append(Placement(rotation, radius * out))
        return cls(robot, placements, preload=preload)

    @classmethod
    def button(
        cls,
        robot: ContactRobot,
        *,
        stiffness: float,
        direction: Sequence[float] = (0.0, 0.0, -1.0),
        load: float = 0.0,
    ) -> Grasp:
        """One finger (in its own frame) pressing a button (the thesis' cube with a known
        force): the button's cap sticks to the contact points and turns with them, a spring of
        `stiffness` and a constant force `load` push it back along `direction` (from the
        contact face outwards: -z for the Finger), the only coordinate controlled. Three
        contact points on a line do not hold a turn about that line: the cap has no such
        coordinate."""
        rest = robot.rest()
        points = robot.contact_positions(rest)
        n = np.asarray(direction, dtype=float)
        n = n / np.linalg.norm(n)
        guide = block_diag(np.eye(3), _turns_held(points))
        along = guide.T @ np.concatenate([n, np.zeros(3)])
        return cls(
            robot,
            [Placement()],
            guide=guide,
            stiffness=stiffness * np.outer(along, along),
            load=-load * along,
            weights=np.abs(along),
            rest=rest,
        )

    @property
    def n_fingers(self) -> int:
        return len(self.placements)

    def start(self) -> tuple[list[State], Pose]:
        """The fingers and the object at the start: every actuator at the preload (reached in
        steps of PRELOAD_STEP from rest, the object's equilibrium at each), the object where
        that leaves it. Computed once; copies are returned."""
        if self._start is None:
            states = [self.rest_state.copy() for _ in self.placements]
            pose = self.object.reference
            steps = math.ceil(abs(self.preload) / PRELOAD_STEP)
            for k in range(1, steps + 1):
                command = np.full((self.n_fingers, self.robot.n_a), self.preload * k / steps)
                states, pose = self.settle(states, pose, command)
            self._start = (states, pose)
        states, pose = self._start
        return [s.copy() for s in states], pose

    def hold(self, states: list[State], pose: Pose, delta_a: np.ndarray) -> list[State]:
        """The fingers' equilibria with their actuators at delta_a (fingers, actuators) and
        their contact points on the object at `pose`."""
        world = self.object.positions(pose).reshape(self.n_fingers, -1, 3)
        reference = self.robot.reference
        return [
            self.robot.solve(state, d, (place.to_local(x) - reference).ravel())
            for state, d, place, x in zip(
                states, np.atleast_2d(delta_a), self.placements, world, strict=True
            )
        ]

    def contact_forces(self, states: list[State]) -> np.ndarray:
        """lambda_c on the fingers, in the world frame, finger after finger."""
        return np.concatenate(
            [
                b @ self.robot.split(s.actuation)[1]
                for b, s in zip(self.rotations, states, strict=True)
            ]
        )

    def residual(self, states: list[State], pose: Pose) -> np.ndarray:
        """J_c^T lambda_c - T_ext: the generalised force left on the object (zero at its
        equilibrium)."""
        j = self.object.jacobian(pose)
        return j.T @ self.contact_forces(states) - self.object.external_load(pose)

    def predict(self, states: list[State], pose: Pose, delta_a: np.ndarray) -> Pose:
        """The object's pose for the actuator displacements delta_a, linearised with the exact
        condensed problems at the equilibrium (states, pose): the actuator forces that reach
        delta_a once the contact forces and the pose are eliminated (Eq. 5.13), then X."""
        problems = [self.robot.problem(s) for s in states]
        obj = self.object
        held = object_problem(
            self,
            problems,
            pose,
            np.zeros(obj.n_coordinates),
            obj.external_load(pose),
            obj.stiffness,
            np.ones(obj.n_coordinates),
        )
        sa = held.problem.slices["actuator"]
        forces = np.linalg.solve(
            held.problem.compliance[sa, sa], np.ravel(delta_a) - held.problem.free_distance[sa]
        )
        return obj.displaced(pose, held.increment(forces))

    def settle(
        self,
        states: list[State],
        pose: Pose,
        delta_a: np.ndarray,
        *,
        tolerance: float = 1e-5,
        max_iterations: int = 30,
    ) -> tuple[list[State], Pose]:
        """The exact plant: the object's quasi-static equilibrium on the FEM fingers, their
        actuators at delta_a, from the equilibrium (states, pose).

        The exact condensed problems at `states` predict the new pose (Eq. 5.13 with the
        actuators' displacements imposed), then Newton on the object's coordinates with the
        tangent J_c^T S J_c + K (S = d lambda_c / d delta_c of every finger, exact), kept while
        the change shrinks fast (it costs a condensation per finger), until the change falls
        below `tolerance`; DivergenceError if it does not within `max_iterations`."""
        pose = self.predict(states, pose, delta_a)
        robot, obj = self.robot, self.object
        tangent, previous = None, math.inf
        for _ in range(max_iterations):
            states = self.hold(states, pose, delta_a)
            residual = self.residual(states, pose)
            if tangent is not None:
                step = -np.linalg.solve(tangent, residual)
            if tangent is None or np.linalg.norm(step) > 0.25 * previous:
                pairs = zip(self.rotations, states, strict=True)
                stiffness = block_diag(*[b @ robot.contact_stiffness(s) @ b.T for b, s in pairs])
                j = obj.jacobian(pose)
                tangent = j.T @ stiffness @ j + obj.stiffness
                step = -np.linalg.solve(tangent, residual)
            previous = float(np.linalg.norm(step))
            if previous <= tolerance:
                return states, pose
            pose = obj.displaced(pose, step)
        raise DivergenceError(
            f"the held object found no equilibrium in {max_iterations} Newton iterations (last"
            f" change {previous:.3g})",
            step=states[0].step,
            cause="solver",
        )


def _turns_held(points: np.ndarray) -> np.ndarray:
    """Orthonormal axes (columns) of the rotations that move some of `points`: all three, or
    the two across the line the points lie on (to 0.1 % of their spread: a turn about a line
    they are that close to is all but free)."""
    centered = points - points.mean(axis=0)
    _, values, axes = np.linalg.svd(centered)
    if values[1] > 1e-3 * values[0]:
        return np.eye(3)
    return axes[1:].T


@dataclass(frozen=True)
class ObjectProblem:
    """Eq. 5.12-5.13 for the fingers' condensed problems at one step.

    With x_c = x_c_prev + J_c dq (Eq. 5.10), x_c = W_ca lambda_a + W_cc lambda_c + x_c_free
    (Eq. 5.12, world frame, fingers stacked) and the object's equilibrium
    J_c^T lambda_c = T - K dq, D = J_c^T W_cc^-1 gives

        dq = A lambda_a + B,  A = (D J_c + K)^-1 D W_ca,
                              B = (D J_c + K)^-1 [D (x_c_free - x_c_prev) + T]  (Eq. 5.13).

    `problem` is the condensed problem left after eliminating lambda_c and dq: its actuator
    rows are every finger's actuators, delta_a = W'_aa lambda_a + delta'_a_free with
    W'_aa = W_aa - W_ac W_cc^-1 W_ca + (D W_ca)^T A (symmetric), its effector rows the
    object's coordinates, weight (dq - dq_goal): what the inverse QP (Eq. 2.15) takes.
    """

    problem: CondensedProblem
    a: np.ndarray
    b: np.ndarray
    contact_compliance: np.ndarray
    contact_actuator: np.ndarray
    contact_free: np.ndarray
    contact_previous: np.ndarray
    jacobian: np.ndarray

    def increment(self, lambda_a: np.ndarray) -> np.ndarray:
        """dq = A lambda_a + B."""
        return self.a @ lambda_a + self.b

    def contact_forces(self, lambda_a: np.ndarray) -> np.ndarray:
        """lambda_c (world) from Eq. 5.12 at the pose reached."""
        reached = self.contact_previous + self.jacobian @ self.increment(lambda_a)
        return np.linalg.solve(
            self.contact_compliance,
            reached - self.contact_actuator @ lambda_a - self.contact_free,
        )

    def actuator_displacements(self, lambda_a: np.ndarray) -> np.ndarray:
        """delta_a = W_aa lambda_a + W_ac lambda_c + delta_a_free, every finger's."""
        sa = self.problem.slices["actuator"]
        return self.problem.compliance[sa, sa] @ lambda_a + self.problem.free_distance[sa]


def object_problem(
    grasp: Grasp,
    problems: Sequence[CondensedProblem],
    pose: Pose,
    goal_increment: np.ndarray,
    load: np.ndarray,
    stiffness: np.ndarray,
    weights: np.ndarray,
) -> ObjectProblem:
    """Eq. 5.13 from the fingers' condensed problems (their own frames, layout order), the
    object at `pose`, T = `load` there and the spring `stiffness` K folded in; the effector
    rows are weights * (dq - goal_increment)."""
    robot, obj = grasp.robot, grasp.object
    reference = robot.reference
    w_aa = block_diag(*[p.block("actuator", "actuator") for p in problems])
    fingers = list(zip(grasp.rotations, problems, strict=True))
    w_ca = block_diag(*[b @ p.block("contact", "actuator") for b, p in fingers])
    w_cc = block_diag(*[b @ p.block("contact", "contact") @ b.T for b, p in fingers])
    x_free = np.concatenate(
        [
            place.to_world(reference + p.free("contact").reshape(-1, 3)).ravel()
            for place, p in zip(grasp.placements, problems, strict=True)
        ]
    )
    a_free = np.concatenate([p.free("actuator") for p in problems])
    x_prev = obj.positions(pose).ravel()
    j = obj.jacobian(pose)
    d = np.linalg.solve(w_cc, j).T  # D = J^T W_cc^-1
    wcc_inv_wca = np.linalg.solve(w_cc, w_ca)
    m = d @ j + stiffness
    m = 0.5 * (m + m.T)
    a = np.linalg.solve(m, d @ w_ca)
    b = np.linalg.solve(m, d @ (x_free - x_prev) + load)
    w_aa_held = w_aa - w_ca.T @ wcc_inv_wca + (d @ w_ca).T @ a
    a_free_held = a_free + wcc_inv_wca.T @ (x_prev + j @ b - x_free)
    w_ea = weights[:, None] * a
    w_ee = weights[:, None] * np.linalg.inv(m) * weights[None, :]
    n_a, n_q = a.shape[1], a.shape[0]
    compliance = np.block([[0.5 * (w_aa_held + w_aa_held.T), w_ea.T], [w_ea, w_ee]])
    free = np.concatenate([a_free_held, weights * (b - goal_increment)])
    slices = {
        "actuator": slice(0, n_a),
        "effector": slice(n_a, n_a + n_q),
        "contact": slice(n_a + n_q, n_a + n_q),
    }
    return ObjectProblem(
        CondensedProblem(compliance, free, slices), a, b, w_cc, w_ca, x_free, x_prev, j
    )


class ManipulationController:
    """Algorithm 1: inverse control of a held object's pose from condensed models of its
    fingers, starting from lambda_c = 0.

    Each step, from the fingers' measured states and the object's measured pose: W and
    delta_free of every finger (`source`), X = A lambda_a + B (Eq. 5.13), the inverse QP for
    lambda_a within the effort and course bounds (Eq. 2.15), the new lambda_c (Eq. 5.12) and the
    actuator displacements delta_a = W_aa lambda_a + W_ac lambda_c + delta_a_free to apply.

    Args:
        source: the fingers' condensed problems, one for every finger: a
            LearnedCondensedModel, or the ContactRobot for the exact ones.
        load: the object's load T_cube in B: "previous" (Algorithm 1: J_c^T lambda_c of the
            previous step, the forces being unknown) or "known" (the object's own load and
            spring, RigidObject.external_load: a button).
        course: a box of actuator displacements the control keeps to (one finger's; e.g. the
            learned model's input box).
        weights: of the object's coordinates in the QP (default: the grasp's).
    """

    def __init__(
        self,
        grasp: Grasp,
        source: CondensedSource,
        *,
        load: Literal["previous", "known"] = "previous",
        course: Box | None = None,
        regularisation: float = 1e-3,
        weights: np.ndarray | None = None,
    ) -> None:
        if load not in ("previous", "known"):
            raise ModelError(f"load must be 'previous' or 'known', got {load!r}")
        source.layout.check_matches(grasp.robot.layout, f"{grasp.robot.model.name} with contacts")
        self.grasp = grasp
        self.source = source
        self.load = load
        self.regularisation = regularisation
        self.actuators = within(grasp.robot.layout.actuators, course) * grasp.n_fingers
        self.weights = grasp.weights if weights is None else np.asarray(weights, dtype=float)
        self.contact_forces = np.zeros(grasp.object.points.size)
        self.predicted: Pose | None = None

    def step(self, states: list[State], pose: Pose, goal: Pose) -> np.ndarray:
        """Actuator displacements (fingers, actuators) that bring the object from `pose`
        towards `goal`."""
        grasp, obj = self.grasp, self.grasp.object
        problems = [self.source.problem(s) for s in states]
        if self.load == "known":
            load, stiffness = obj.external_load(pose), obj.stiffness
        else:
            load = obj.jacobian(pose).T @ self.contact_forces
            stiffness = np.zeros_like(obj.stiffness)
        goal_increment = obj.guide.T @ goal.minus(pose)
        held = object_problem(grasp, problems, pose, goal_increment, load, stiffness, self.weights)
        measured = np.concatenate([grasp.robot.split(s.displacement)[0] for s in states])
        lambda_a = solve_inverse(
            held.problem,
            self.actuators,
            measured,
            regularisation=self.regularisation,
            course="soft",
        ).actuation
        self.contact_forces = held.contact_forces(lambda_a)
        self.predicted = obj.displaced(pose, held.increment(lambda_a))
        return held.actuator_displacements(lambda_a).reshape(grasp.n_fingers, -1)


@dataclass
class ObjectTrajectory:
    """Goals and what the plant reached, one entry per goal.

    Attributes:
        reached: the object's poses at equilibrium after the goal's last control iteration.
        forces: J_c^T lambda_c there, lambda_c on the fingers: at equilibrium the object's
            load T_ext, balanced by the opposite push of the fingers.
        commands: the actuator displacements applied, (goals, fingers, actuators).
    """

    goals: list[Pose]
    reached: list[Pose]
    forces: np.ndarray
    commands: np.ndarray

    @property
    def centers(self) -> np.ndarray:
        return np.array([p.center for p in self.reached])

    @property
    def errors(self) -> np.ndarray:
        """Distance between the goal's and the reached centre, per goal."""
        return np.linalg.norm(self.centers - np.array([g.center for g in self.goals]), axis=1)

    @property
    def rotation_errors(self) -> np.ndarray:
        """Angle between the goal's and the reached orientation (rad), per goal."""
        pairs = zip(self.reached, self.goals, strict=True)
        return np.array([np.linalg.norm(r.minus(g)[3:]) for r, g in pairs])


def follow_object(
    grasp: Grasp,
    controller: ManipulationController,
    goals: Sequence[Pose],
    *,
    iterations: int = 3,
) -> ObjectTrajectory:
    """Drive the exact plant (:meth:`Grasp.settle`) through `goals`, `iterations` control
    steps per goal, the controller reading the fingers' states and the object's pose."""
    states, pose = grasp.start()
    reached, forces, commands = [], [], []
    for goal in goals:
        for _ in range(iterations):
            delta_a = controller.step(states, pose, goal)
            states, pose = grasp.settle(states, pose, delta_a)
        reached.append(pose)
        forces.append(grasp.object.jacobian(pose).T @ grasp.contact_forces(states))
        commands.append(delta_a)
    return ObjectTrajectory(list(goals), reached, np.array(forces), np.array(commands))


GRASP_ITERATIONS = 1  # control steps towards each sampled pose of the gripper's cube


def grasp_chunk(plan: CollectionPlan, points: np.ndarray, model: Model) -> Split:
    """Gripper sampling (the thesis' contact datasets): the cube of a gripper of `model`s
    driven towards each sampled displacement from its pose in the grasp, in a row (each from
    the previous one's equilibrium), by GRASP_ITERATIONS steps of the controller with the exact
    matrices on the exact plant; one sample per finger (its own frame) at the equilibrium
    reached: near the goal, short of it by the linearisation's error over the step and by what
    the QP's least squares trade for the cube's tilt."""
    robot = ContactRobot.for_plan(model, plan)
    grasp = Grasp.gripper(robot)
    rest = robot.layout.pack(robot.problem(grasp.rest_state))
    course = Box([lo for lo, _ in plan.actuator_bounds], [hi for _, hi in plan.actuator_bounds])
    controller = ManipulationController(grasp, robot, load="known", course=course)
    states, pose = grasp.start()
    origin = pose
    rows: list[dict[str, np.ndarray]] = []
    no_design = np.zeros(0)
    for point in np.atleast_2d(points):
        goal = origin.displaced(np.resize(np.append(point, np.zeros(6)), 6))
        try:
            reached, at = states, pose
            for _ in range(GRASP_ITERATIONS):
                commands = controller.step(reached, at, goal)
                reached, at = grasp.settle(reached, at, commands)
        except (DivergenceError, SolverError):  # kept NaN; the next starts from the last
            command = np.concatenate([np.full(robot.n_a, np.nan), point])
            rows += [failed_row(command, no_design, robot.layout)] * grasp.n_fingers
            continue
        states, pose = reached, at
        rows += [
            sample_row(robot, s, np.concatenate([d, point]), no_design, rest)
            for s, d in zip(states, commands, strict=True)
        ]
    return Split(**{f.name: np.array([r[f.name] for r in rows]) for f in fields(Split)})
