"""A world of rigid bodies, obstacles and gravity, stepped with frictional contact in the
constraint space: the velocity-level time stepping of Stewart and Trinkle (IJNME 39, 1996) and
Anitescu and Potra (1997) written in the compliance form of the deformable step, with the free
motion, M^-1 and the contact Jacobian of the bodies (pliant.fem.rigid, whose module docstring
states the scheme) and one contact solver for both (pliant.constraints.friction).

Joints (:mod:`pliant.constraints.rigid_joints`: ball, sliding, locked axes) add bilateral rows
G after the contact rows: W gains h^2 G M^-1 G^T and its coupling with the contacts,
delta_free the joints' delta(q) + h G u_free; the joint rows are eliminated (their Schur
complement, :func:`pliant.constraints.attachment.eliminate`) before the contact solver sees
the problem, and u = u_free + h M^-1 (J^T lambda_c + G^T lambda_j). A spring's rows
(RestSpring) add their compliance 1 / k to W's diagonal: the spring acts at the end of the
step. Without joints the step is the contact step alone.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from pliant.constraints.attachment import eliminate
from pliant.constraints.condensed import CondensedProblem
from pliant.constraints.friction import ContactForces, ContactReport, solve_contact
from pliant.constraints.rigid_joints import (
    RigidJoint,
    check_joints,
    joint_compliance,
    joint_rows,
)
from pliant.errors import DivergenceError, ModelError, SolverError
from pliant.fem.rigid import (
    KinematicBody,
    RigidBody,
    contact_twist_jacobian,
    free_twists,
    integrate_poses,
    inverse_mass,
    speed_bound,
)
from pliant.geometry.collision import ContactSet, Shape, collide


@dataclass
class RigidState:
    """Poses and twists of the dynamic bodies, time, step count and the last contact forces
    (kept so that a restored state warm-starts exactly as it did the first time)."""

    positions: np.ndarray  # (n, 3)
    rotations: np.ndarray  # (n, 3, 3)
    velocities: np.ndarray  # (n, 3)
    angular_velocities: np.ndarray  # (n, 3)
    time: float = 0.0
    step: int = 0
    contacts: ContactForces = field(default_factory=ContactForces.empty)

    def copy(self) -> RigidState:
        return RigidState(
            self.positions.copy(),
            self.rotations.copy(),
            self.velocities.copy(),
            self.angular_velocities.copy(),
            self.time,
            self.step,
            self.contacts.copy(),
        )

    def allclose(self, other: RigidState, *, atol: float = 0.0) -> bool:
        pairs = (
            (self.positions, other.positions),
            (self.rotations, other.rotations),
            (self.velocities, other.velocities),
            (self.angular_velocities, other.angular_velocities),
        )
        return self.step == other.step and all(
            np.allclose(a, b, rtol=0.0, atol=atol) for a, b in pairs
        )


class RigidWorld:
    """Dynamic rigid bodies, obstacles (kinematic bodies, or plain shapes held still) and
    gravity, and the joints between the bodies (:mod:`pliant.constraints.rigid_joints`). The
    model: built once; what changes lives in RigidState."""

    def __init__(
        self,
        bodies: list[RigidBody],
        obstacles: list[KinematicBody | Shape] = (),
        *,
        gravity=(0.0, 0.0, -9.81),
        joints: list[RigidJoint] = (),
    ) -> None:
        self.bodies = list(bodies)
        self.joints = list(joints)
        check_joints(self.joints, self.bodies)
        self.obstacles = [
            o if isinstance(o, KinematicBody) else KinematicBody(o) for o in obstacles
        ]
        self.gravity = np.asarray(gravity, dtype=float).reshape(3)
        if not np.all(np.isfinite(self.gravity)):
            raise ModelError("gravity must be finite")
        shapes = [c.shape for c in self.colliders]
        if len({id(s) for s in shapes}) != len(shapes):
            raise ModelError("each body and obstacle needs its own shape object")

    @property
    def colliders(self) -> list[RigidBody | KinematicBody]:
        """Bodies then obstacles: a contact's index_a / index_b index this list."""
        return [*self.bodies, *self.obstacles]

    def initial_state(self) -> RigidState:
        b = self.bodies
        return RigidState(
            np.array([x.position for x in b]).reshape(-1, 3),
            np.array([x.rotation for x in b]).reshape(-1, 3, 3),
            np.array([x.velocity for x in b]).reshape(-1, 3),
            np.array([x.angular_velocity for x in b]).reshape(-1, 3),
        )

    def inverse_inertias(self, state: RigidState) -> np.ndarray:
        """(n, 3, 3) world inverse inertia R I^-1 R^T of each body."""
        inv = np.array([b.inverse_inertia for b in self.bodies]).reshape(-1, 3, 3)
        return state.rotations @ inv @ state.rotations.transpose(0, 2, 1)

    def energy(self, state: RigidState) -> float:
        """Kinetic plus gravitational potential energy: sum 1/2 m v^2 + 1/2 w.I w - m g.x."""
        total = 0.0
        for i, b in enumerate(self.bodies):
            w = state.rotations[i].T @ state.angular_velocities[i]
            total += 0.5 * b.mass * state.velocities[i] @ state.velocities[i]
            total += 0.5 * w @ b.inertia @ w - b.mass * self.gravity @ state.positions[i]
        return float(total)


class RigidSolver:
    """Steps a RigidWorld (see the module docstring for the scheme).

    Args:
        world: the bodies and obstacles.
        dt: time step h.
        margin: contacts are detected up to this gap plus the distance the fastest bodies can
            travel in the step (speculative contacts).
        tolerance, max_iterations: of the contact solver (tolerance in length units).
    """

    def __init__(
        self,
        world: RigidWorld,
        dt: float = 1e-3,
        *,
        margin: float = 0.0,
        tolerance: float = 1e-10,
        max_iterations: int = 1000,
    ) -> None:
        if not (math.isfinite(dt) and dt > 0.0):
            raise ModelError(f"the time step must be finite and > 0, got {dt!r}")
        if not (math.isfinite(margin) and margin >= 0.0):
            raise ModelError(f"the margin must be finite and >= 0, got {margin!r}")
        self.world = world
        self.dt = float(dt)
        self.margin = float(margin)
        self.tolerance = tolerance
        self.max_iterations = max_iterations
        self.last_report = ContactReport()
        self.last_contacts = ContactSet.empty()

    def _detect(self, state: RigidState, speed: float) -> ContactSet:
        """Pose every shape, then collide each body with the later colliders whose boxes,
        grown by the margin, overlap its own."""
        world, h = self.world, self.dt
        colliders = world.colliders
        for i, b in enumerate(world.bodies):
            b.shape.set_pose(state.positions[i], state.rotations[i])
            b.shape.set_twist(state.velocities[i], state.angular_velocities[i])
        for o in world.obstacles:
            o.place(state.time, h)
            if o.shape.bounds() is not None:
                speed = max(
                    speed, speed_bound(o.shape, o.shape.linear_velocity, o.shape.angular_velocity)
                )
        # Two bodies approach each other at most at the sum of their largest point speeds.
        margin = self.margin + 2.0 * h * speed
        boxes = [c.shape.bounds() for c in colliders]
        found = []
        for i in range(len(world.bodies)):
            for j in range(i + 1, len(colliders)):
                a, b = boxes[i], boxes[j]
                if b is not None and (np.any(a[0] > b[1] + margin) or np.any(b[0] > a[1] + margin)):
                    continue
                pair = collide(colliders[i].shape, colliders[j].shape, margin)
                k = len(pair)
                found.append(replace(pair, index_a=np.full(k, i), index_b=np.full(k, j)))
        return ContactSet.concatenate(found)

    def _contact_jacobian(
        self, state: RigidState, contacts: ContactSet
    ) -> tuple[np.ndarray, np.ndarray]:
        """J (3k, 6n) with J u the velocity of a's contact point relative to b's in each
        contact frame, and the part of that relative velocity due to obstacles (k, 3)."""
        n, k = len(self.world.bodies), len(contacts)
        colliders = self.world.colliders
        frames = contacts.frames
        jac = contact_twist_jacobian(
            frames, contacts.point_a, contacts.index_a, state.positions, n
        ) - contact_twist_jacobian(frames, contacts.point_b, contacts.index_b, state.positions, n)
        obstacle_velocity = np.zeros((k, 3))
        for c in range(k):
            for i, point, sign in (
                (int(contacts.index_a[c]), contacts.point_a[c], 1.0),
                (int(contacts.index_b[c]), contacts.point_b[c], -1.0),
            ):
                if i >= n:
                    velocity = colliders[i].shape.point_velocity(point[None])[0]
                    obstacle_velocity[c] += sign * frames[c] @ velocity
        return jac, obstacle_velocity

    def _with_joints(self, state, jac, delta_free, u_free):
        """The contact rows then the joints' (module docstring): the rows' Jacobian on the
        twists and their delta_free."""
        world, h = self.world, self.dt
        distance, rows = joint_rows(world.joints, world.bodies, state.positions, state.rotations)
        jac = np.vstack([jac, rows])
        delta_free = np.concatenate([delta_free, distance + h * (rows @ u_free)])
        return jac, delta_free

    def step(self, state: RigidState) -> RigidState:
        """The state one step h later (see the module docstring); raises DivergenceError if
        it is not finite."""
        world, h = self.world, self.dt
        bodies = world.bodies
        twists_free = free_twists(
            bodies,
            state.rotations,
            state.velocities,
            state.angular_velocities,
            world.gravity,
            h,
        )
        speed = max(
            (speed_bound(b.shape, u[:3], u[3:]) for b, u in zip(bodies, twists_free, strict=True)),
            default=0.0,
        )
        contacts = self._detect(state, speed)
        k = len(contacts)
        u_free = twists_free.reshape(-1)
        m_inv = inverse_mass(bodies, state.rotations, h)
        jac, obstacle_velocity = self._contact_jacobian(state, contacts)
        delta_free = h * (jac @ u_free + obstacle_velocity.reshape(-1))
        delta_free[0::3] += contacts.gap
        compliance = h * h * (jac @ m_inv @ jac.T)
        colliders = world.colliders
        mu = np.sqrt(
            np.array([colliders[i].friction for i in contacts.index_a])
            * np.array([colliders[j].friction for j in contacts.index_b])
        )
        empty = slice(0, 0)
        slices = {"actuator": empty, "effector": empty, "contact": slice(0, 3 * k)}
        if world.joints:  # their rows after the contacts', eliminated before the contact solve
            jac, delta_free = self._with_joints(state, jac, delta_free, u_free)
            slices["attachment"] = slice(3 * k, delta_free.size)
            compliance = h * h * (jac @ m_inv @ jac.T)
            rows = np.arange(3 * k, delta_free.size)
            compliance[rows, rows] += joint_compliance(world.joints)  # springs' rows
        problem = CondensedProblem(0.5 * (compliance + compliance.T), delta_free, slices)
        elimination = None
        if world.joints:
            try:
                elimination = eliminate(problem)
            except SolverError as exc:  # joints that hold the same motion twice
                raise DivergenceError(
                    f"step {state.step + 1}: the joints' {exc}", step=state.step + 1, cause="solver"
                ) from exc
        solution = solve_contact(
            problem if elimination is None else elimination.problem,
            mu,
            initial=state.contacts.warm_start(contacts),
            tolerance=self.tolerance,
            max_iterations=self.max_iterations,
        )
        forces = solution.forces if elimination is None else elimination.full(solution.forces)
        u = (u_free + h * (m_inv @ (jac.T @ forces))).reshape(-1, 6)
        if not np.all(np.isfinite(u)):
            raise DivergenceError(
                f"step {state.step + 1}: the rigid bodies' velocities became non-finite;"
                f" reduce the time step (now {h})",
                step=state.step + 1,
                cause="non-finite",
            )
        positions, rotations = integrate_poses(state.positions, state.rotations, u, h)
        self.last_report = solution.report
        self.last_contacts = contacts
        return RigidState(
            positions,
            rotations,
            u[:, :3].copy(),
            u[:, 3:].copy(),
            state.time + h,
            state.step + 1,
            ContactForces.from_multipliers(contacts, solution.contact_forces),
        )
