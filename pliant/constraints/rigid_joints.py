"""Joints between rigid bodies (or a rigid body and the world): bilateral rows on the bodies'
twists, solved with their contacts in the rigid bodies' step (:mod:`pliant.solvers.rigid`).

A point fixed in body a at r_a (body frame) is at p_a = x_a + R_a r_a and moves at J(p_a) u_a,
J = [I, -[p_a - x_a]x] (:func:`pliant.fem.rigid.twist_jacobian`). Each joint gives rows

    delta(q) (r,),   G = d delta / d(h u)  (r, 6n),

and the step holds delta(q) + h G u = 0 at its end (u the twists after the step), the
multipliers lambda being the forces G^T lambda the joint exerts: the same first-order
linearisation as an attachment's rows (:mod:`pliant.constraints.attachment`), so that what the
joint is left open by at the start of a step (the poses' second-order drift, O((h w)^2 |r|))
is closed over the step.

* :class:`BallJoint` (SOFA's BilateralInteractionConstraint on Vec3 points): a point of body a
  held on a point of body b, or on a fixed point of the world; three rows (world axes).
* :class:`SlidingJoint` (SOFA's SlidingConstraint): a point of body a held on the line through
  two points (fixed in the world, or in body b's frame); two rows, the point's offset from the
  line along two normals of it. The normals are taken at the start of the step.
* :class:`AxisLock` (SOFA's PartialFixedConstraint on a Rigid3 frame): components of a body's
  linear or angular velocity (world axes) held at zero; velocity rows (delta = 0).
* :class:`RestSpring` (SOFA's RestShapeSpringsForceField on a Rigid3 frame): the body's centre
  pulled to a rest position by a stiffness k, its rotation to a rest rotation by an angular
  stiffness: compliant rows, delta = x - x_rest and log(R R_rest^T), held at delta = -lambda / k
  at the end of the step (an implicit spring: the step solves (W + 1/k) lambda = -delta_free).

A joint's rows have a compliance (:meth:`RigidJoint.compliance`): zero for the rigid joints.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from pliant.errors import ModelError
from pliant.fem.rigid import RigidBody, twist_jacobian
from pliant.geometry.rotation import check_rotation, log_map


def _point(value, what: str) -> np.ndarray:
    p = np.asarray(value, dtype=float).reshape(-1)
    if p.shape != (3,) or not np.all(np.isfinite(p)):
        raise ModelError(f"{what} must be a finite 3-vector, got {value!r}")
    return p


def _check_body(body, what: str) -> RigidBody | None:
    if body is not None and not isinstance(body, RigidBody):
        raise ModelError(f"{what} must be a dynamic RigidBody (or None: the world)")
    return body


class RigidJoint:
    """Rows on rigid bodies' twists (see the module docstring); subclasses give `n_rows`,
    `bodies` and `rows`."""

    name: str
    n_rows: int
    bodies: tuple[RigidBody | None, ...]

    def rows(
        self, positions: np.ndarray, rotations: np.ndarray, index: dict[int, int], n: int
    ) -> tuple[np.ndarray, np.ndarray]:
        """(delta (r,), G (r, 6n)) at the bodies' poses; `index` maps id(body) to its index."""
        raise NotImplementedError

    def compliance(self) -> np.ndarray:
        """(r,) each row's compliance 1 / k (zero: held exactly)."""
        return np.zeros(self.n_rows)

    def _hold(self, body_a, body_b, name: str) -> None:
        """Take the joint's name and bodies: a RigidBody, and another one or None."""
        self.name = name
        self.body_a = _check_body(body_a, f"{name}: body_a")
        if self.body_a is None:
            raise ModelError(f"{name}: body_a must be a RigidBody")
        self.body_b = _check_body(body_b, f"{name}: body_b")
        if self.body_b is self.body_a:
            raise ModelError(f"{name}: a joint holds two different bodies")
        self.bodies = (self.body_a, self.body_b)

    @staticmethod
    def _carried(body, local, positions, rotations, index):
        """(world point, its index or -1) of `local` fixed in `body` (None: the world)."""
        if body is None:
            return local, -1
        i = index[id(body)]
        return positions[i] + rotations[i] @ local, i

    @staticmethod
    def _velocity_rows(g, i, point, centre, directions, sign) -> None:
        """Add sign * directions . J(point) on body i to g (r, 6n)."""
        if i < 0:
            return
        jac = twist_jacobian((point - centre)[None])[0]  # (3, 6)
        g[:, 6 * i : 6 * i + 6] += sign * directions @ jac


class BallJoint(RigidJoint):
    """A point of `body_a` (at `point_a` in its frame) held on a point of `body_b` (at
    `point_b` in b's frame), or on the world point `point_b` when `body_b` is None."""

    n_rows = 3

    def __init__(self, body_a, point_a, body_b=None, point_b=None, *, name: str = "ball joint"):
        self._hold(body_a, body_b, name)
        self.point_a = _point(point_a, f"{name}: point_a")
        if point_b is None:  # where a's point is now, in b's frame or the world
            world = self.body_a.position + self.body_a.rotation @ self.point_a
            b = self.body_b
            point_b = world if b is None else b.rotation.T @ (world - b.position)
        self.point_b = _point(point_b, f"{name}: point_b")

    def rows(self, positions, rotations, index, n):
        pa, ia = self._carried(self.body_a, self.point_a, positions, rotations, index)
        pb, ib = self._carried(self.body_b, self.point_b, positions, rotations, index)
        g = np.zeros((3, 6 * n))
        eye = np.eye(3)
        self._velocity_rows(g, ia, pa, positions[ia], eye, 1.0)
        if ib >= 0:
            self._velocity_rows(g, ib, pb, positions[ib], eye, -1.0)
        return pa - pb, g


class SlidingJoint(RigidJoint):
    """A point of `body_a` (at `point` in its frame) held on the line through `start` and
    `end` (world points, or points in `body_b`'s frame): two rows, the point's offset from the
    line along two unit normals of it. The line is unbounded: SOFA's SlidingConstraint also
    stops the point at the segment's ends (a unilateral third row past either), which this
    joint does not."""

    n_rows = 2

    def __init__(self, body_a, point, start, end, body_b=None, *, name: str = "sliding joint"):
        self._hold(body_a, body_b, name)
        self.point = _point(point, f"{name}: point")
        self.start = _point(start, f"{name}: start")
        self.end = _point(end, f"{name}: end")
        axis = self.end - self.start
        if not np.linalg.norm(axis) > 1e-12 * max(1.0, float(np.abs(self.start).max())):
            raise ModelError(f"{name}: the line's two points coincide")

    def normals(self, rotations, index) -> np.ndarray:
        """(2, 3) two unit normals of the line (world axes)."""
        axis = self.end - self.start
        if self.body_b is not None:
            axis = rotations[index[id(self.body_b)]] @ axis
        axis = axis / np.linalg.norm(axis)
        helper = np.eye(3)[int(np.argmin(np.abs(axis)))]
        first = np.cross(axis, helper)
        first /= np.linalg.norm(first)
        return np.array([first, np.cross(axis, first)])

    def rows(self, positions, rotations, index, n):
        pa, ia = self._carried(self.body_a, self.point, positions, rotations, index)
        on_line, ib = self._carried(self.body_b, self.start, positions, rotations, index)
        normals = self.normals(rotations, index)
        g = np.zeros((2, 6 * n))
        self._velocity_rows(g, ia, pa, positions[ia], normals, 1.0)
        if ib >= 0:  # b's material point where a's point is
            self._velocity_rows(g, ib, pa, positions[ib], normals, -1.0)
        return normals @ (pa - on_line), g


class AxisLock(RigidJoint):
    """Components of a body's linear and angular velocity held at zero (world axes): SOFA's
    PartialFixedConstraint ``fixedDirections`` (vx vy vz wx wy wz) on a Rigid3 frame."""

    def __init__(self, body, directions: Sequence[bool], *, name: str = "axis lock"):
        self.name = name
        self.body = _check_body(body, f"{name}: body")
        if self.body is None:
            raise ModelError(f"{name}: body must be a RigidBody")
        locked = np.asarray(directions, dtype=bool).reshape(-1)
        if locked.shape != (6,):
            raise ModelError(f"{name}: six directions (vx vy vz wx wy wz), got {directions!r}")
        self.axes = np.flatnonzero(locked)
        if not self.axes.size:
            raise ModelError(f"{name}: no direction locked")
        self.n_rows = int(self.axes.size)
        self.bodies = (self.body,)

    def rows(self, positions, rotations, index, n):
        i = index[id(self.body)]
        g = np.zeros((self.n_rows, 6 * n))
        g[np.arange(self.n_rows), 6 * i + self.axes] = 1.0
        return np.zeros(self.n_rows), g


class RestSpring(RigidJoint):
    """A body's centre pulled to `rest_position` by `stiffness` (force / length) and, with an
    `angular_stiffness` (torque / radian) > 0, its rotation to `rest_rotation`; by default the
    body's initial pose. `rest_position` and `rest_rotation` may be reassigned between steps."""

    def __init__(
        self,
        body,
        stiffness: float,
        angular_stiffness: float = 0.0,
        rest_position=None,
        rest_rotation=None,
        *,
        name: str = "rest spring",
    ):
        self.name = name
        self.body = _check_body(body, f"{name}: body")
        if self.body is None:
            raise ModelError(f"{name}: body must be a RigidBody")
        k, k_turn = float(stiffness), float(angular_stiffness)
        if not (np.isfinite(k) and k > 0.0 and np.isfinite(k_turn) and k_turn >= 0.0):
            raise ModelError(
                f"{name}: the stiffness must be finite and > 0 and the angular one >= 0, got"
                f" {stiffness!r} and {angular_stiffness!r}"
            )
        self.stiffness, self.angular_stiffness = k, k_turn
        position = self.body.position if rest_position is None else rest_position
        self.rest_position = _point(position, f"{name}: rest_position")
        rotation = self.body.rotation if rest_rotation is None else rest_rotation
        self.rest_rotation = check_rotation(rotation, name=f"{name}: rest_rotation")
        self.n_rows = 6 if k_turn > 0.0 else 3
        self.bodies = (self.body,)

    def compliance(self) -> np.ndarray:
        c = np.full(self.n_rows, 1.0 / self.stiffness)
        c[3:] = 1.0 / self.angular_stiffness if self.n_rows == 6 else 0.0
        return c

    def rows(self, positions, rotations, index, n):
        i = index[id(self.body)]
        g = np.zeros((self.n_rows, 6 * n))
        g[np.arange(self.n_rows), 6 * i + np.arange(self.n_rows)] = 1.0
        delta = positions[i] - self.rest_position
        if self.n_rows == 6:  # the turn from rest, world axes (its rate: the angular velocity)
            delta = np.concatenate([delta, log_map(rotations[i] @ self.rest_rotation.T)])
        return delta, g


def joint_compliance(joints: Sequence[RigidJoint]) -> np.ndarray:
    """All joints' row compliances, in order."""
    return np.concatenate([j.compliance() for j in joints]) if joints else np.zeros(0)


def joint_rows(
    joints: Sequence[RigidJoint], bodies: Sequence[RigidBody], positions, rotations
) -> tuple[np.ndarray, np.ndarray]:
    """All joints' (delta (r,), G (r, 6n)) stacked, in order."""
    index = {id(b): i for i, b in enumerate(bodies)}
    n = len(bodies)
    parts = [j.rows(positions, rotations, index, n) for j in joints]
    if not parts:
        return np.zeros(0), np.zeros((0, 6 * n))
    return np.concatenate([p[0] for p in parts]), np.vstack([p[1] for p in parts])


def check_joints(joints: Sequence[RigidJoint], bodies: Sequence[RigidBody]) -> None:
    """ModelError where a joint is not one or holds a body that is not one of `bodies`."""
    known = {id(b) for b in bodies}
    for j in joints:
        if not isinstance(j, RigidJoint):
            raise ModelError(f"{j!r} is not a rigid joint")
        for b in j.bodies:
            if b is not None and id(b) not in known:
                raise ModelError(f"{j.name}: its body {b.name} is not one of the rigid bodies")
