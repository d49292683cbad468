"""Rigid bodies, kinematic bodies, points attached to a rigid frame, deformable nodes driven by
a kinematic body (`DrivenNodes`), and the pieces of their step with frictional contact in the
constraint space: the free motion, M^-1 and the contact Jacobian (`RigidStep`,
`contact_twist_jacobian`), which serve a world of rigid bodies (pliant.solvers.rigid) and rigid
bodies coupled to a deformable body by contact (pliant.constraints.contact,
pliant.solvers.implicit_euler).

A rigid body has 6 DoF: the position x of its frame origin (the centre of mass), its rotation R
(body -> world), and the twist u = (v, w): linear and angular velocity, both in the world.
A point fixed in the body at r (body frame) is at p = x + R r and moves at
v + w x (p - x) = J(p) u with J(p) = [I, -[p - x]x] (`twist_jacobian`).

The step is the velocity-level time stepping of Stewart and Trinkle (IJNME 39, 1996) and
Anitescu and Potra (1997), written in the same compliance form as the deformable step
(pliant.solvers.implicit_euler) so that one contact solver serves both. With h the step,
M = diag(m I, R I_body R^T) and J the contact Jacobian (rows n, t1, t2 of each contact):

    free motion   v_free = v + h g,   w_free = w - h I^-1 (w x I w)  (implicit gyroscopic term,
                  one Newton step in the body frame; Catto, GDC 2015); a body with velocity
                  damping c (drag in a fluid, an air table) divides its free twist and its
                  M^-1 by 1 + h c (the damping force -c M u taken at the end of the step),
    constraints   delta = W lambda + delta_free,  W = h^2 J M^-1 J^T,
                  delta_free = (phi, 0, 0) + h J u_free - h (relative obstacle motion),
    correction    u = u_free + h M^-1 J^T lambda,
    positions     x += h v,   R = exp(h [w]x) R  (symplectic Euler on the exponential map),

with lambda a force held over the step (impulse h lambda) obeying Signorini and Coulomb
(pliant.constraints.friction). delta_n = phi + h n . (relative velocity) is the gap at the end
of the step: contacts are inelastic and speculative (detected within a margin that grows with
the speeds, they act only if the gap would close within the step).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from pliant.errors import DivergenceError, ModelError
from pliant.fem import rigid_kernels
from pliant.fem.material import check_friction
from pliant.geometry.collision import Box, BoxUnion, Capsule, Shape, Sphere, cross
from pliant.geometry.inertia import box_inertia, box_union_inertia, capsule_inertia, sphere_inertia
from pliant.geometry.rotation import axis_angle, check_rotation, exp_map, log_map, skew

Trajectory = Callable[[float], tuple[np.ndarray, np.ndarray]]
#: Poses a kinematic body keeps memoised (the latest times asked for).
_POSES_KEPT = 4


def twist_jacobian(arms: np.ndarray) -> np.ndarray:
    """(k, 3, 6) d(point velocity)/d(v, w) = [I, -[arm]x] for arms p - x (k, 3)."""
    arms = np.asarray(arms, dtype=float).reshape(-1, 3)
    jac = np.zeros((arms.shape[0], 3, 6))
    jac[:, :, :3] = np.eye(3)
    jac[:, :, 3:] = -np.array([skew(a) for a in arms]).reshape(-1, 3, 3)
    return jac


class AttachedPoints:
    """Points fixed in a rigid frame, at `local_points` (k, 3) in that frame: p = x + R r."""

    def __init__(self, local_points: np.ndarray) -> None:
        r = np.asarray(local_points, dtype=float)
        if r.ndim != 2 or r.shape[1] != 3 or not np.all(np.isfinite(r)):
            raise ModelError(f"attached points must be a finite (k, 3) array, got {r.shape}")
        self.local_points = r.copy()

    def positions(self, position: np.ndarray, rotation: np.ndarray) -> np.ndarray:
        return position + self.local_points @ rotation.T

    def velocities(self, rotation: np.ndarray, velocity, angular_velocity) -> np.ndarray:
        """v + w x (R r)."""
        return velocity + np.cross(angular_velocity, self.local_points @ rotation.T)

    def jacobian(self, rotation: np.ndarray) -> np.ndarray:
        """(k, 3, 6) derivative of the velocities with respect to the twist (v, w)."""
        return twist_jacobian(self.local_points @ rotation.T)


class BodyForce:
    """A force fixed in a rigid body's frame, so that it turns with the body (a follower
    force): `force` at `point`, both in body coordinates (the point from the centre of mass).
    In the world: F = R f and the torque about the centre of mass tau = (R r) x (R f) =
    R (r x f). The step takes it at the start of the step, like gravity (the free motion,
    module docstring).
    """

    def __init__(self, point, force) -> None:
        self.point = np.asarray(point, dtype=float).reshape(-1)
        self.force = np.asarray(force, dtype=float).reshape(-1)
        for label, v in (("point", self.point), ("force", self.force)):
            if v.shape != (3,) or not np.all(np.isfinite(v)):
                raise ModelError(f"BodyForce: the {label} must be a finite 3-vector")

    def wrench(self, rotation: np.ndarray) -> np.ndarray:
        """(6,) the world force F and torque tau about the centre of mass."""
        return np.concatenate([rotation @ self.force, rotation @ np.cross(self.point, self.force)])

    def tangent(self, rotation: np.ndarray) -> np.ndarray:
        """(6, 3) K = -d(F, tau)/d theta for a turn R -> exp([theta]x) R: dF = theta x F, so
        K = [[F]x; [tau]x]."""
        wrench = self.wrench(rotation)
        return np.vstack([skew(wrench[:3]), skew(wrench[3:])])


class WorldForce:
    """A force and a torque about the centre of mass fixed in the world (SOFA's
    ConstantForceField on a Rigid3 frame: ``totalForce`` (fx fy fz tx ty tz)); `force` and
    `torque` may be reassigned between steps (a controller pushing a cart). Taken at the start
    of the step, like gravity."""

    def __init__(self, force=(0.0, 0.0, 0.0), torque=(0.0, 0.0, 0.0)) -> None:
        self.force = np.asarray(force, dtype=float).reshape(-1)
        self.torque = np.asarray(torque, dtype=float).reshape(-1)
        for label, v in (("force", self.force), ("torque", self.torque)):
            if v.shape != (3,) or not np.all(np.isfinite(v)):
                raise ModelError(f"WorldForce: the {label} must be a finite 3-vector")

    def wrench(self, rotation: np.ndarray) -> np.ndarray:
        """(6,) the force and torque (the same whatever the body's rotation)."""
        return np.concatenate([self.force, self.torque])


def _check_friction(friction: float, name: str) -> float:
    if not np.isscalar(friction):
        raise ModelError(f"{name}: the friction coefficient must be one number")
    return float(check_friction(friction, 1)[0])


def speed_bound(shape: Shape, velocity: np.ndarray, angular_velocity: np.ndarray) -> float:
    """Largest speed of a point of the shape: |v| + |w| (bounding radius about its origin)."""
    return float(
        np.linalg.norm(velocity) + np.linalg.norm(angular_velocity) * shape.bounding_radius()
    )


class RigidBody:
    """A rigid body carrying a bounded collision shape; its frame origin is its centre of mass.

    Args:
        shape: collision shape, defined in the body frame's coordinates (its pose is set from
            the state every step).
        mass: m > 0.
        inertia: (3, 3) symmetric positive definite inertia about the centre of mass, body
            frame; default from the shape for a Sphere, a Box, a Capsule or a BoxUnion (solid,
            uniform density; a BoxUnion's boxes centred on its frame origin).
        friction: Coulomb coefficient; a contact uses sqrt(mu_a mu_b) (as Box2D and Bullet).
        linear_damping, angular_damping: velocity damping c >= 0 (1/s): a force -c m v and a
            torque -c I w, e.g. the drag of a fluid or of an air table (as Bullet's damping).
        position, rotation, velocity, angular_velocity: the initial state (default: the
            shape's pose, at rest).
        forces: forces fixed in the body's frame (:class:`BodyForce`), turning with it, or
            in the world (:class:`WorldForce`).
        held: six flags, the components of the twist (v_x, v_y, v_z, w_x, w_y, w_z, world
            frame) held at zero (SOFA's PartialFixedConstraint on a Rigid3 frame, a cart on
            a rail): the step projects them out of the free twist and of M^-1, so that no
            force moves the body along them (default: none held).
    """

    def __init__(
        self,
        shape: Shape,
        mass: float,
        inertia: np.ndarray | None = None,
        *,
        friction: float = 0.5,
        linear_damping: float = 0.0,
        angular_damping: float = 0.0,
        position=None,
        rotation: np.ndarray | None = None,
        velocity=(0.0, 0.0, 0.0),
        angular_velocity=(0.0, 0.0, 0.0),
        name: str = "body",
        forces: Sequence[BodyForce | WorldForce] = (),
        held: Sequence[bool] | None = None,
    ) -> None:
        self.name = name
        self.forces = list(forces)
        self.held = None
        if held is not None:
            flags = np.asarray(held)
            if flags.shape != (6,) or flags.dtype != bool:
                raise ModelError(f"{name}: held must be six booleans, got {held!r}")
            if flags.all():
                raise ModelError(f"{name}: every motion held: a fixed body is an obstacle")
            self.held = flags.copy() if flags.any() else None
        if shape.bounds() is None:
            raise ModelError(
                f"{name}: a rigid body needs a bounded shape, got a {type(shape).__name__}"
            )
        if not (math.isfinite(mass) and mass > 0.0):
            raise ModelError(f"{name}: the mass must be finite and > 0, got {mass!r}")
        if inertia is None:
            if isinstance(shape, Sphere):
                inertia = sphere_inertia(mass, shape.radius)
            elif isinstance(shape, Box):
                inertia = box_inertia(mass, shape.half_extents)
            elif isinstance(shape, Capsule):
                inertia = capsule_inertia(mass, shape.radius, shape.half_length)
            elif isinstance(shape, BoxUnion):
                if np.linalg.norm(shape.centroid) > 1e-9 * shape.bounding_radius():
                    raise ModelError(
                        f"{name}: a rigid body's frame origin is its centre of mass; the boxes"
                        f" of its BoxUnion have their centroid at {shape.centroid.tolist()}"
                    )
                inertia = box_union_inertia(mass, shape)
            else:
                raise ModelError(f"{name}: give the inertia of a {type(shape).__name__}")
        inertia = np.asarray(inertia, dtype=float)
        if inertia.shape != (3, 3) or not np.all(np.isfinite(inertia)):
            raise ModelError(f"{name}: the inertia must be a finite 3x3 matrix")
        if np.abs(inertia - inertia.T).max() > 1e-12 * np.abs(inertia).max():
            raise ModelError(f"{name}: the inertia tensor must be symmetric")
        smallest = float(np.linalg.eigvalsh(inertia).min())
        if not smallest > 0.0:
            raise ModelError(
                f"{name}: the inertia tensor must be positive definite (smallest principal"
                f" moment {smallest:.3g})"
            )
        self.shape = shape
        self.mass = float(mass)
        self.inertia = inertia.copy()
        self.inverse_inertia = np.linalg.inv(inertia)
        self.friction = _check_friction(friction, name)
        for label, c in (("linear", linear_damping), ("angular", angular_damping)):
            if not (math.isfinite(c) and c >= 0.0):
                raise ModelError(f"{name}: the {label} damping must be finite and >= 0, got {c!r}")
        self.linear_damping = float(linear_damping)
        self.angular_damping = float(angular_damping)
        self.position = np.array(shape.position if position is None else position, dtype=float)
        self.rotation = check_rotation(shape.rotation if rotation is None else rotation)
        self.velocity = np.asarray(velocity, dtype=float).reshape(3)
        self.angular_velocity = np.asarray(angular_velocity, dtype=float).reshape(3)
        for label, v in (("position", self.position), ("velocity", self.velocity)):
            if v.shape != (3,) or not np.all(np.isfinite(v)):
                raise ModelError(f"{name}: the initial {label} must be a finite 3-vector")
        if not np.all(np.isfinite(self.angular_velocity)):
            raise ModelError(f"{name}: the initial angular velocity must be finite")


class KinematicBody:
    """A shape whose pose is prescribed: fixed (trajectory None) or a function of time
    t -> (position, rotation), e.g. `rail(...)` for a cart, `servo(...)` for a servo horn.

    Its twist over a step [t, t + h] is the one carrying pose(t) to pose(t + h):
    v = (x(t+h) - x(t)) / h, w = log(R(t+h) R(t)^T) / h.
    """

    def __init__(
        self,
        shape: Shape,
        trajectory: Trajectory | None = None,
        *,
        friction: float = 0.5,
        name: str = "obstacle",
    ) -> None:
        self.shape = shape
        self.name = name
        self.friction = _check_friction(friction, name)
        fixed = (shape.position.copy(), shape.rotation.copy())
        self.trajectory = trajectory if trajectory is not None else (lambda t: fixed)
        # The poses asked for lately, by time, and the trajectory they are of: a step asks
        # for t and t + h repeatedly (its drive, its look-ahead, the contacts' obstacles).
        self._poses: dict[float, tuple[np.ndarray, np.ndarray]] = {}
        self._poses_of: Trajectory | None = None
        self._carried: dict = {}  # what `carry` gave each owner: (the pose, its result)

    def forget(self) -> None:
        """Drop the memoised poses: after its trajectory was changed in place (an environment
        retargeting a cart), the pose at a time asked before is no longer the same."""
        self._poses = {}
        self._carried = {}

    def pose(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """The pose at t (read-only arrays; one object for as long as it is memoised)."""
        poses = self._poses
        if self._poses_of is not self.trajectory:
            poses.clear()
            self._poses_of = self.trajectory
        pose = poses.get(t)
        if pose is not None:
            return pose
        position, rotation = self.trajectory(t)
        position = np.asarray(position, dtype=float).reshape(3)
        if not np.all(np.isfinite(position)):
            raise ModelError(f"{self.name}: the trajectory gave a non-finite position at t={t}")
        pose = (position.copy(), check_rotation(rotation, name=f"{self.name} rotation at t={t}"))
        for array in pose:
            array.flags.writeable = False
        if len(poses) >= _POSES_KEPT:
            del poses[next(iter(poses))]  # the oldest
        poses[t] = pose
        return pose

    def carry(
        self, owner, t: float, place: Callable[[np.ndarray, np.ndarray], np.ndarray]
    ) -> np.ndarray:
        """`place(position, rotation)` at the pose at t (the positions of what the body
        carries: driven nodes, a clamped rod end), memoised per `owner` for its last pose: a
        step asks for the driven nodes at t + h three times (the drive, its velocities, the
        driven result) and the next step again. A pose is one object for as long as it is
        memoised (a new one after :meth:`forget`), and the memo holds it, so that its
        identity is the key. The result is read-only."""
        pose = self.pose(t)
        memo = self._carried.get(owner)
        if memo is not None and memo[0] is pose:
            return memo[1]
        out = place(*pose)
        out.flags.writeable = False
        self._carried[owner] = (pose, out)
        return out

    def twist(self, t: float, dt: float) -> tuple[np.ndarray, np.ndarray]:
        x0, r0 = self.pose(t)
        x1, r1 = self.pose(t + dt)
        return (x1 - x0) / dt, log_map(r1 @ r0.T) / dt

    def place(self, t: float, dt: float) -> None:
        """Pose the shape at t and give it the twist of the step [t, t + dt]."""
        self.shape.set_pose(*self.pose(t))
        self.shape.set_twist(*self.twist(t, dt))


def rail(
    origin, axis, displacement: Callable[[float], float], rotation: np.ndarray | None = None
) -> Trajectory:
    """A cart on a straight rail: x(t) = origin + s(t) axis / |axis|, constant rotation."""
    o = np.asarray(origin, dtype=float).reshape(3)
    a = np.asarray(axis, dtype=float).reshape(3)
    a = a / np.linalg.norm(a)
    r = np.eye(3) if rotation is None else check_rotation(rotation)
    return lambda t: (o + float(displacement(t)) * a, r)


def servo(
    pivot, axis, angle: Callable[[float], float], position, rotation: np.ndarray | None = None
) -> Trajectory:
    """A part turned by a servo about `axis` through `pivot`: at angle 0 its frame is at
    (position, rotation); at angle a it is rotated by Rot(axis, a) about the pivot."""
    c = np.asarray(pivot, dtype=float).reshape(3)
    x0 = np.asarray(position, dtype=float).reshape(3)
    r0 = np.eye(3) if rotation is None else check_rotation(rotation)

    def pose(t: float) -> tuple[np.ndarray, np.ndarray]:
        turn = axis_angle(axis, float(angle(t)))
        return c + turn @ (x0 - c), turn @ r0

    return pose


def motor(
    pivot,
    axis,
    speed: float,
    position,
    rotation: np.ndarray | None = None,
    *,
    start: float = 0.0,
) -> Trajectory:
    """A part on a DC motor's shaft: turned about `axis` through `pivot` at a constant `speed`
    (rad/s) from time `start` (s), as :func:`servo` with the angle speed (t - start)."""
    if not math.isfinite(speed):
        raise ModelError(f"a motor's speed must be finite, got {speed!r}")
    return servo(pivot, axis, lambda t: speed * max(t - start, 0.0), position, rotation)


class DrivenNodes:
    """Held nodes of a deformable body carried by a kinematic body (a cart on a rail, a
    gripper's translating base): a rigid attachment of the nodes to the carrier's frame.

    Each node keeps its coordinates r_i = R(0)^T (X_i - x(0)) in the carrier's frame at t = 0
    (X_i its rest position), so that it is at p_i(t) = x(t) + R(t) r_i: at rest at t = 0.
    The nodes must be fixed nodes of the body (held, not free DoFs); the dynamic step moves
    them to p_i(t + h) and lets the free DoFs feel that motion within the same implicit step
    (through the coupling stiffness K_fp, see pliant.solvers.implicit_euler).

    Args:
        nodes: indices of the carried nodes (a subset of the body's fixed nodes).
        carrier: the kinematic body whose prescribed pose carries them.
    """

    def __init__(self, nodes: np.ndarray, carrier: KinematicBody, *, name: str = "driven") -> None:
        self.nodes = np.unique(np.asarray(nodes, dtype=np.int64).reshape(-1))
        if self.nodes.size == 0:
            raise ModelError(f"{name}: no node to drive")
        self.carrier = carrier
        self.name = name
        self.local_points: np.ndarray | None = None

    def attach(self, rest_positions: np.ndarray) -> None:
        """Fix the nodes' coordinates in the carrier's frame (called once by the Model)."""
        if self.nodes.max() >= rest_positions.shape[0] or self.nodes.min() < 0:
            raise ModelError(
                f"{self.name}: node indices must lie in [0, {rest_positions.shape[0]})"
            )
        self.carrier.forget()  # positions carried before were another body's
        position, rotation = self.carrier.pose(0.0)
        self.local_points = (rest_positions[self.nodes] - position) @ rotation

    def positions(self, t: float) -> np.ndarray:
        """(k, 3) world positions of the nodes at time t: x(t) + R(t) r_i (read-only)."""
        if self.local_points is None:
            raise ModelError(f"{self.name}: not attached to a body (give it to a Model)")
        return self.carrier.carry(self, t, self._place)

    def _place(self, position: np.ndarray, rotation: np.ndarray) -> np.ndarray:
        return position + self.local_points @ rotation.T


def free_angular_velocity(
    inertia: np.ndarray, rotation: np.ndarray, angular_velocity: np.ndarray, dt: float
) -> np.ndarray:
    """One Newton step on I (w - w0) + h w x I w = 0 in the body frame (Catto 2015)."""
    w0 = rotation.T @ angular_velocity
    jac = inertia + dt * (skew(w0) @ inertia - skew(inertia @ w0))
    gyroscopic = cross(w0[None], (inertia @ w0)[None])[0]  # w0 x I w0
    return rotation @ (w0 - np.linalg.solve(jac, dt * gyroscopic))


def free_twists(
    bodies: list[RigidBody],
    rotations: np.ndarray,
    velocities: np.ndarray,
    angular_velocities: np.ndarray,
    gravity: np.ndarray,
    dt: float,
) -> np.ndarray:
    """(n, 6) twists u_free = (v + h g, w_free) after a step without contact (module
    docstring), plus h M^-1 (F, tau) of the bodies' own forces (:class:`BodyForce`)."""
    twists = np.zeros((len(bodies), 6))
    for i, b in enumerate(bodies):
        twists[i, :3] = velocities[i] + dt * np.asarray(gravity)
        twists[i, 3:] = free_angular_velocity(b.inertia, rotations[i], angular_velocities[i], dt)
        if b.forces:
            wrench = sum(f.wrench(rotations[i]) for f in b.forces)
            twists[i, :3] += dt * wrench[:3] / b.mass
            world_inverse = rotations[i] @ b.inverse_inertia @ rotations[i].T
            twists[i, 3:] += dt * world_inverse @ wrench[3:]
        twists[i, :3] /= 1.0 + dt * b.linear_damping
        twists[i, 3:] /= 1.0 + dt * b.angular_damping
        if b.held is not None:
            twists[i, b.held] = 0.0
    return twists


def inverse_mass(bodies: list[RigidBody], rotations: np.ndarray, dt: float) -> np.ndarray:
    """(6n, 6n) block-diagonal M^-1 = diag(I / m, R I^-1 R^T) of the bodies (world frame),
    each block divided by 1 + h c for the bodies' velocity damping c."""
    n = len(bodies)
    m_inv = np.zeros((n, 6, n, 6))
    for i, b in enumerate(bodies):
        m_inv[i, :3, i, :3] = np.eye(3) / (b.mass * (1.0 + dt * b.linear_damping))
        m_inv[i, 3:, i, 3:] = (rotations[i] @ b.inverse_inertia @ rotations[i].T) / (
            1.0 + dt * b.angular_damping
        )
        if b.held is not None:  # P M^-1 P, P the projection off the held components
            m_inv[i, b.held, i] = 0.0
            m_inv[i, :, i, b.held] = 0.0
    return m_inv.reshape(6 * n, 6 * n)


def integrate_poses(
    positions: np.ndarray, rotations: np.ndarray, twists: np.ndarray, dt: float
) -> tuple[np.ndarray, np.ndarray]:
    """x + h v and exp(h [w]x) R for each body (symplectic Euler on the exponential map)."""
    twists = twists.reshape(-1, 6)
    new_rotations = np.array(
        [exp_map(dt * twists[i, 3:]) @ rotations[i] for i in range(len(twists))]
    ).reshape(-1, 3, 3)
    return positions + dt * twists[:, :3], new_rotations


@dataclass(frozen=True)
class RigidStep:
    """Rigid bodies over one step of a coupled model, before contact: their poses at the start,
    their free twists u_free (module docstring) and M^-1. The contact forces lambda then give
    u = u_free + h M^-1 G^T lambda, G the contact rows' twist Jacobian."""

    positions: np.ndarray  # (n, 3)
    rotations: np.ndarray  # (n, 3, 3)
    twists_free: np.ndarray  # (n, 6)
    inverse_mass: np.ndarray  # (6n, 6n)

    @classmethod
    def free(
        cls,
        bodies: list[RigidBody],
        positions: np.ndarray,
        rotations: np.ndarray,
        velocities: np.ndarray,
        angular_velocities: np.ndarray,
        gravity: np.ndarray,
        dt: float,
    ) -> RigidStep:
        twists = free_twists(bodies, rotations, velocities, angular_velocities, gravity, dt)
        return cls(positions, rotations, twists, inverse_mass(bodies, rotations, dt))

    def speeds(self, bodies: list[RigidBody]) -> np.ndarray:
        """Largest speed of a point of each body's shape over the step (free motion)."""
        return np.array(
            [
                speed_bound(b.shape, u[:3], u[3:])
                for b, u in zip(bodies, self.twists_free, strict=True)
            ]
        )

    def twists(
        self, rigid_jacobian: np.ndarray, forces: np.ndarray, dt: float, step: int
    ) -> np.ndarray:
        """(n, 6) u = u_free + h M^-1 G^T lambda; DivergenceError if not finite."""
        u = self.twists_free.reshape(-1) + dt * (self.inverse_mass @ (rigid_jacobian.T @ forces))
        if not np.all(np.isfinite(u)):
            raise DivergenceError(
                f"step {step}: the rigid bodies' velocities became non-finite; reduce the time"
                f" step (now {dt})",
                step=step,
                cause="non-finite",
            )
        return u.reshape(-1, 6)


def contact_twist_jacobian(
    frames: np.ndarray, points: np.ndarray, bodies: np.ndarray, centres: np.ndarray, n: int
) -> np.ndarray:
    """(3k, 6n) rows (n, t1, t2) . J(p) of the velocity of each contact point `points[c]`
    carried by body `bodies[c]` (centre of mass `centres[bodies[c]]`); rows of contacts whose
    body index is outside [0, n) are zero.

    A row f gives f . (v + w x a) = f . v + (a x f) . w, a = p - x the arm (compiled: the
    plain definition is frames[c] @ twist_jacobian(points[c] - centres[bodies[c]]))."""
    return rigid_kernels.contact_twist_rows(
        frames, points, np.asarray(bodies, dtype=np.int64), centres, n
    )
