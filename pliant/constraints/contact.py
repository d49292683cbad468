"""Contact of a deformable body with obstacles: what the model holds, what a step detects.

A :class:`Contacts` is part of a model, like its actuators: the obstacle shapes (static, or
kinematic with a prescribed pose and twist), a friction coefficient per shape, and the points of
the body that collide (by default its surface nodes that are not fixed). Each step detects the
points within ``margin`` of a shape and adds their rows (normal, two tangents) to the
constraint space; the step's contact problem is then solved with the actuators
(:func:`pliant.constraints.friction.solve_contact`).

The margin is SOFA's alarm distance: a point is given a contact row before it touches, so that
a step cannot jump through a surface it was not told about. It must exceed the largest
distance a surface point travels towards an obstacle in one step.

Rigid bodies of the model (:class:`pliant.fem.rigid.RigidBody`) are detected too, posed at the
step's start: the body's points against their shapes, and each rigid body against the
obstacles and the later rigid bodies (:func:`pliant.geometry.collision.collide`, with a
margin grown by the distance the bodies can travel in the step). These rows also move the
rigid bodies: with u their twists and G (3 rows per contact, `CoupledContact.rigid_jacobian`)
the velocity of the contact point of side a relative to side b due to them,

    delta = H (x-part, as above) + h G u,   u = u_free + h M^-1 G^T lambda,

so that the step's compliance gains h^2 G M^-1 G^T and its free distance h G u_free
(pliant.solvers.implicit_euler), and lambda acts on both sides of each contact.

Pieces of the body touching each other (:class:`pliant.constraints.surface.SurfaceContact`,
points of one piece against the current triangles of another) add rows on the relative point
of the two pieces, with the obstacles' law, after the planes' rows.

Self-contact planes (:class:`PointPlanes`, SoftRobots' UnilateralPlaneConstraint) keep a
point of the body on one side of the plane through three others. The point's offset from the
three's centroid, d = p_a - (p_b + p_c + p_d) / 3, is linear in the nodes: it is one more
embedded point of the contacts, against the plane through the origin with the triangle's normal
(taken at the step's start), never out of reach, without friction. The step solves its rows
with the other contacts', through the same columns.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from dataclasses import fields, replace

import numpy as np

from pliant.constraints.base import Constraint, EmbeddedPoints, JacobianRows
from pliant.constraints.friction import ContactConstraint
from pliant.constraints.surface import RigidSurfaceContact, SurfaceContact
from pliant.errors import ContactError, ContactMarginWarning
from pliant.fem.material import check_friction
from pliant.fem.rigid import RigidBody, RigidStep, contact_twist_jacobian
from pliant.geometry.collision import ContactSet, Shape, collide, detect, shape_velocities


class PointPlanes:
    """Points of the body held on one side of the plane through three other points of it
    (SoftRobots' UnilateralPlaneConstraint), each a unilateral frictionless contact.

    With p_a the held point and p_b, p_c, p_d the plane's, the normal n = (p_c - p_b) x
    (p_d - p_b) (reversed by `flip`) and d = p_a - (p_b + p_c + p_d) / 3, the row is

        delta = n/|n| . d >= 0,   lambda >= 0,   delta lambda = 0,

    its gradient n/|n| on p_a and -n/(3|n|) on each of p_b, p_c, p_d (SoftRobots' row, up to
    the normal's length, which scales lambda only): the plane's reaction is shared equally by
    its three points, and the normal is held over a step. The gap n/|n| . (p_a - p_b) equals
    n/|n| . d since the centroid lies in the plane.

    Args:
        points: 4 k embedded points: p_a, p_b, p_c, p_d of each of the k planes in turn.
        flip: (k,) or one bool: reverse the normal of each plane.
        names: what to call each plane in errors.
    """

    def __init__(self, points: EmbeddedPoints, flip=False, names=None) -> None:
        if len(points) == 0 or len(points) % 4:
            raise ContactError(f"point planes need four points each, got {len(points)} points")
        if not points.linear:
            raise ContactError("point planes need points linear in the nodes (EmbeddedPoints)")
        k = len(points) // 4
        self.flip = np.broadcast_to(np.asarray(flip, dtype=bool), (k,)).copy()
        self.names = [f"plane {j}" for j in range(k)] if names is None else list(names)
        if len(self.names) != k:
            raise ContactError(f"{k} point planes but {len(self.names)} names")
        self.points = points
        # d = p_a - (p_b + p_c + p_d) / 3: the nodes of the four points side by side.
        m = points.nodes.shape[1]
        nodes = points.nodes.reshape(k, 4 * m)
        weights = (
            points.weights.reshape(k, 4, m) * np.array([1.0, -1 / 3, -1 / 3, -1 / 3])[None, :, None]
        )
        self.offsets = EmbeddedPoints.at_nodes(np.zeros(k, dtype=np.int64))
        self.offsets.nodes, self.offsets.weights = nodes, weights.reshape(k, 4 * m)

    def __len__(self) -> int:
        return len(self.flip)

    def normals(self, x: np.ndarray) -> np.ndarray:
        """(k, 3) unit normals of the planes at positions `x`; ContactError for a plane whose
        three points are aligned."""
        p = self.points.positions(x).reshape(-1, 4, 3)
        n = np.cross(p[:, 2] - p[:, 1], p[:, 3] - p[:, 1])
        n[self.flip] *= -1.0
        size = np.linalg.norm(n, axis=1)
        scale = np.ptp(p.reshape(-1, 3), axis=0).max() if p.size else 1.0
        flat = np.flatnonzero(~(size > 1e-12 * max(scale, 1e-300) ** 2))
        if flat.size:
            raise ContactError(
                f"{self.names[flat[0]]}: its three plane points are aligned (no normal)"
            )
        return n / size[:, None]

    def contacts(self, x: np.ndarray, first: int, index_b: int, thickness: float) -> ContactSet:
        """The planes' contacts at `x`, every one (open or closed): side a the offset d of
        plane j, numbered ``first + j`` among the contacts' points, side b the plane."""
        normal = self.normals(x)
        d = self.offsets.positions(x)
        gap = np.einsum("ki,ki->k", normal, d)
        k = len(self)
        return ContactSet(
            first + np.arange(k, dtype=np.int64),
            np.full(k, index_b, dtype=np.int64),
            np.zeros(k, dtype=np.int64),
            gap,
            normal,
            d - thickness * normal,  # the rows' origin (point_a + thickness n) is d itself
            d - gap[:, None] * normal,
        )


class Contacts:
    """Obstacles a body touches, and the contact law with each.

    Args:
        shapes: collision shapes (Plane, Box, Sphere, Capsule, TriangleMesh), posed in the world.
        friction: Coulomb coefficient mu, one for all shapes or one per shape.
        margin: detection (alarm) distance in model units; None: 2 % of the body's bounding-box
            diagonal.
        points: the colliding points of the body; None: its `colliding_nodes()` (the surface
            nodes of tetrahedra, the centreline nodes of a rod, that are not held). Either
            :class:`EmbeddedPoints` or a mapping with the same interface (`positions`,
            `displacement`, `rows`, `nodes`, `weights`, `linear`), as a surface skinned onto
            a rod's frames (:class:`pliant.proxy.Skinning`).
        tolerance: contact solver tolerance: the largest correction of a contact's displacement
            in a last Gauss-Seidel sweep (model length unit; 1e-5 mm by default).
        max_iterations: contact solver sweeps before a ContactConvergenceWarning.
        thickness: radius of the colliding points, balls rather than points (a rod's
            centreline nodes): a point touches a shape or a rigid body when its signed
            distance equals the thickness; a contact's gap is the distance less the thickness.
        planes: self-contact planes of the body (:class:`PointPlanes`), solved with the
            contacts; `shapes` may then be empty. After the model attaches the contacts,
            `points` holds the colliding points, then the planes' offsets.
        surfaces: contacts between pieces of the body (:class:`SurfaceContact`: points of one
            piece against the surface of another), detected within `margin` each step and
            solved with the others; `shapes` may then be empty. Their rows follow the
            obstacles' and the planes'.
        rigid_surfaces: points carried by the model's rigid bodies against triangles of the
            body (:class:`RigidSurfaceContact`), coupled with the bodies as their shapes'
            contacts are; their rows follow the surface contacts'.
    """

    #: The surface contacts between pieces of the body (none unless given).
    surfaces: Sequence[SurfaceContact] = ()
    #: The contacts of rigid bodies' points with the body's triangles (none unless given).
    rigid_surfaces: Sequence[RigidSurfaceContact] = ()

    def __init__(
        self,
        shapes: Sequence[Shape],
        *,
        friction: float | Sequence[float] = 0.0,
        margin: float | None = None,
        points: EmbeddedPoints | None = None,
        tolerance: float = 1e-5,
        max_iterations: int = 1000,
        thickness: float = 0.0,
        planes: PointPlanes | None = None,
        surfaces: Sequence[SurfaceContact] = (),
        rigid_surfaces: Sequence[RigidSurfaceContact] = (),
    ) -> None:
        self.shapes = list(shapes)
        self.planes = planes
        if surfaces:  # else the class's empty default: the model's attributes stay as they were
            self.surfaces = list(surfaces)
        if rigid_surfaces:
            self.rigid_surfaces = list(rigid_surfaces)
        if not (self.shapes or planes is not None or surfaces or rigid_surfaces) and points is None:
            raise ContactError(
                "Contacts needs at least one shape (or point planes, or surface contacts)"
            )
        for surface in rigid_surfaces:
            if not isinstance(surface, RigidSurfaceContact):
                raise ContactError(f"not a RigidSurfaceContact: {surface!r}")
        for surface in surfaces:
            if not isinstance(surface, SurfaceContact):
                raise ContactError(f"not a SurfaceContact: {surface!r}")
        for shape in self.shapes:
            if not isinstance(shape, Shape):
                raise ContactError(f"not a collision shape: {shape!r}")
        self.friction = check_friction(friction, len(self.shapes))
        if margin is not None and not (math.isfinite(margin) and margin > 0):
            raise ContactError(f"the contact margin must be finite and > 0, got {margin!r}")
        if not (math.isfinite(tolerance) and tolerance > 0):
            raise ContactError(f"the contact tolerance must be finite and > 0, got {tolerance!r}")
        if max_iterations < 1:
            raise ContactError(f"max_iterations must be >= 1, got {max_iterations}")
        if not (math.isfinite(thickness) and thickness >= 0):
            raise ContactError(f"the contact thickness must be finite and >= 0, got {thickness!r}")
        self.margin = margin
        self.points = points
        self.tolerance = float(tolerance)
        self.max_iterations = int(max_iterations)
        self.thickness = float(thickness)
        self.bodies: list[RigidBody] = []
        self._carried: np.ndarray | None = None  # (points, bodies): point held by the body
        # (colliding points,) True where a point does not collide with the shapes now (an
        # instrument's nodes waiting behind its entry), set between steps; None: all collide
        self.resting: np.ndarray | None = None

    def attach(self, body, rigid_bodies: Sequence[RigidBody] = ()) -> None:
        """Resolve the defaults against the body and take the model's rigid bodies (called
        once by the Model)."""
        self.bodies = list(rigid_bodies)
        self._colliders = [*self.shapes, *(b.shape for b in self.bodies)]
        if len({id(s) for s in self._colliders}) != len(self._colliders):
            raise ContactError("each obstacle and rigid body needs its own shape object")
        if not (self._colliders or self.planes is not None or self.surfaces):
            raise ContactError("Contacts needs at least one shape or rigid body for its points")
        if self.points is None:
            self.points = EmbeddedPoints.at_nodes(body.colliding_nodes())
        self.n_colliding = len(self.points)
        if self.surfaces and not self.points.linear:
            raise ContactError("surface contacts need colliding points linear in the nodes")
        for surface in self.rigid_surfaces:
            if not any(surface.body is b for b in self.bodies):
                raise ContactError(f"{surface.name}: its rigid body is not one of the model's")
            if surface.vertices.nodes.max() >= body.n_nodes:
                raise ContactError(f"{surface.name}: its triangles read outside the body")
        for surface in self.surfaces:
            for points in (surface.points, surface.vertices):
                if points.nodes.max() >= body.n_nodes:
                    raise ContactError(
                        f"{surface.name}: its points read node {int(points.nodes.max())} of a"
                        f" body of {body.n_nodes} nodes"
                    )
        if self.planes is not None:
            if not self.points.linear:
                raise ContactError("point planes need colliding points linear in the nodes")
            self.points = EmbeddedPoints.stack([self.points, self.planes.offsets])
            self.planes.normals(body.rest_positions)  # aligned plane points: refused now
        if self.margin is None:
            self.margin = 0.02 * body.extent
        self.check_overlap(body.rest_positions)

    def exclude_carried(self, attachments: Sequence) -> None:
        """Points held on a rigid body by an attachment do not collide with that body: each
        colliding point whose nodes are all attached to it (a rod's welded end, the nodes of
        a face holding a payload) sits on its surface and moves with it, so a contact row
        there would be the attachment's rows again, with no compliance of its own."""
        index = {id(b): i for i, b in enumerate(self.bodies)}
        carried = np.zeros((len(self.points), len(self.bodies)), dtype=bool)
        points = self.points
        own = [
            set(nodes[weights > 0].tolist())
            for nodes, weights in zip(points.nodes, points.weights, strict=True)
        ]
        for attachment in attachments:
            held = set(attachment.points.nodes[attachment.points.weights > 0].tolist())
            column = index[id(attachment.body)]
            for j, nodes in enumerate(own):
                carried[j, column] |= bool(nodes) and nodes <= held
        self._carried = carried if carried.any() else None

    def keep_apart(self, bodies: Sequence[RigidBody]) -> None:
        """The body's points do not collide with these rigid bodies (after :meth:`attach`): a
        shape carried by a frame of the body itself (Rigidify's, which SOFA's mesh rides on),
        whose nearby points move with the frame, so that their rows would have no compliance
        of their own but the round-off of the frame's."""
        index = {id(b): i for i, b in enumerate(self.bodies)}
        if self._carried is None:
            self._carried = np.zeros((len(self.points), len(self.bodies)), dtype=bool)
        for body in bodies:
            if id(body) not in index:
                raise ContactError(f"{body.name}: not one of the model's rigid bodies")
            self._carried[:, index[id(body)]] = True

    def check_overlap(self, positions: np.ndarray) -> None:
        """ContactError if a colliding point starts inside a shape deeper than the margin."""
        if not self.shapes:
            return
        found = detect(self._colliding(positions), self.shapes, self.margin, radius=self.thickness)
        found = self._awake(found)
        if len(found) and found.gap.min() < -self.margin:
            i = int(np.argmin(found.gap))
            raise ContactError(
                f"the body overlaps shape {int(found.index_b[i])} at the start: a point lies"
                f" {-found.gap[i]:.3g} inside it (more than the margin {self.margin:.3g});"
                " move the body or the shape"
            )

    def check_travel(self, positions: np.ndarray, displacement: np.ndarray, step: int) -> None:
        """Warn when a colliding point moved further than the margin over a step and ends it
        within the margin of an obstacle or rigid body (as posed at the step's start): it may
        have crossed a surface no row was given for. A point swinging fast far from every
        obstacle is no concern."""
        self._check_surface_travel(positions, displacement, step)
        moved = self.points.displacement(positions, displacement)[: self.n_colliding]
        travel = np.linalg.norm(moved, axis=1)
        fast = np.flatnonzero(travel > self.margin)
        if fast.size == 0 or not self._colliders:
            return
        ends = self._colliding(positions)[fast]
        near = detect(ends, self._colliders, self.margin, radius=self.thickness)
        if self.resting is not None:
            near = _kept(near, ~self.resting[fast[near.index_a]])
        if len(near):
            moved = float(travel[fast[near.index_a]].max())
            warnings.warn(
                f"step {step}: a colliding point moved {moved:.3g}, more than the contact"
                f" margin {self.margin:.3g}, and ended near an obstacle; contacts may have been"
                " missed: raise the margin or reduce the time step",
                ContactMarginWarning,
                stacklevel=3,
            )

    def _check_surface_travel(self, positions, displacement, step: int) -> None:
        """As `check_travel` for the pieces of the body touching each other: a point that
        ends the step near the other piece's surface having come closer to it over the step,
        along the contact's normal, by more than the margin."""
        for s, surface in enumerate(self.surfaces):
            own = np.linalg.norm(surface.points.displacement(positions, displacement), axis=1)
            other = np.linalg.norm(surface.vertices.displacement(positions, displacement), axis=1)
            if own.max() + other.max() <= self.margin:
                continue
            found = surface.detect(positions, self.margin, s)
            if found is None:
                continue
            contacts, nodes, weights, _ = found
            relative = np.einsum("ka,kai->ki", weights, displacement[nodes])
            approach = -np.einsum("ki,ki->k", contacts.normal, relative)
            if approach.max() > self.margin:
                warnings.warn(
                    f"step {step}: {surface.name}: a point came {float(approach.max()):.3g}"
                    " closer to the surface it ends near, more than the contact margin"
                    f" {self.margin:.3g}; contacts may have been missed: raise the margin or"
                    " reduce the time step",
                    ContactMarginWarning,
                    stacklevel=4,
                )
                return

    def constraint(
        self, positions: np.ndarray, dt: float | None, rigid: RigidStep | None = None
    ) -> ContactConstraint | CoupledContact | None:
        """The contact rows at `positions`, or None when no point is within the margin.

        `dt`: the step, to carry moving obstacles' displacement (None: static solve).
        `rigid`: the rigid bodies' step (required when the model has rigid bodies); then the
        rows are a :class:`CoupledContact`.
        """
        points = self._colliding(positions)
        if self.bodies:
            if rigid is None or dt is None:
                raise ContactError("contacts with rigid bodies need a dynamic step (ImplicitEuler)")
            return self._coupled(points, positions, dt, rigid)
        found = (
            self._awake(detect(points, self.shapes, self.margin, radius=self.thickness))
            if self.shapes
            else ContactSet.empty()
        )
        motion = np.zeros((len(found), 3))
        if dt is not None and len(found):
            motion = dt * shape_velocities(found, self.shapes)
        found, friction, motion = self._with_planes(
            positions, found, self.friction[found.index_b], motion
        )
        surface = self.surface_rows(positions) if self.surfaces else None
        if surface is None:
            if len(found) == 0:
                return None
            return ContactConstraint(
                found,
                self.points,
                friction=friction,
                obstacle_displacement=motion,
                thickness=self.thickness,
            )
        rows = ContactConstraint(
            found,
            self.points,
            friction=friction,
            obstacle_displacement=motion,
            thickness=self.thickness,
        )
        return ContactConstraint.joined([rows, surface]) if len(found) else surface

    def surface_rows(self, positions: np.ndarray) -> ContactConstraint | None:
        """The rows of the surface contacts at `positions` (:mod:`pliant.constraints.surface`),
        or None when no point is near another piece. A contact's identity: the point in its
        pair, the pair (numbered after the obstacles, rigid bodies and planes), twice the
        triangle."""
        first = len(self.shapes) + len(self.bodies) + 1
        parts, placed = [], {}
        for s, surface in enumerate(self.surfaces):
            found = surface.detect(positions, self.margin, first + s, placed)
            if found is not None:
                contacts, nodes, weights, origin = found
                parts.append(
                    ContactConstraint.relative(
                        contacts, nodes, weights, origin, friction=surface.friction
                    )
                )
        if not parts:
            return None
        return ContactConstraint.joined(parts) if len(parts) > 1 else parts[0]

    def _rigid_surface_rows(self, positions, rigid: RigidStep, reach: np.ndarray):
        """The rows of the rigid bodies' points against the body's triangles and their G
        (the rigid point is side a: +frames . J(p)), or None when no point is near. A
        contact's identity: the point, the pair (numbered after the surface contacts), twice
        the triangle."""
        first = len(self.shapes) + len(self.bodies) + 1 + len(self.surfaces)
        parts, twist_rows, n = [], [], len(self.bodies)
        for s, surface in enumerate(self.rigid_surfaces):
            i = next(i for i, b in enumerate(self.bodies) if b is surface.body)
            found = surface.detect_rigid(
                positions,
                self.margin + reach[i],
                first + s,
                rigid.positions[i],
                rigid.rotations[i],
            )
            if found is None:
                continue
            contacts, nodes, weights, origin = found
            parts.append(
                ContactConstraint.relative(
                    contacts, nodes, weights, origin, friction=surface.friction
                )
            )
            twist_rows.append(
                contact_twist_jacobian(
                    contacts.frames,
                    contacts.point_a,
                    np.full(len(contacts), i),
                    rigid.positions,
                    n,
                )
            )
        if not parts:
            return None
        rows = ContactConstraint.joined(parts) if len(parts) > 1 else parts[0]
        return rows, np.vstack(twist_rows)

    def _awake(self, found: ContactSet) -> ContactSet:
        """The contacts of the points that are not :attr:`resting`."""
        if self.resting is None or not len(found):
            return found
        return _kept(found, ~self.resting[found.index_a])

    def _colliding(self, positions: np.ndarray) -> np.ndarray:
        """The colliding points' positions (without the planes' offsets)."""
        return self.points.positions(positions)[: self.n_colliding]

    def _with_planes(self, positions, found: ContactSet, friction, motion):
        """The detected contacts followed by every plane's (frictionless, still)."""
        if self.planes is None:
            return found, friction, motion
        index_b = len(self.shapes) + len(self.bodies)
        planes = self.planes.contacts(positions, self.n_colliding, index_b, self.thickness)
        k = len(planes)
        return (
            ContactSet.concatenate([found, planes]),
            np.concatenate([friction, np.zeros(k)]),
            np.vstack([motion, np.zeros((k, 3))]),
        )

    def _coupled(
        self, points: np.ndarray, positions: np.ndarray, dt: float, rigid: RigidStep
    ) -> CoupledContact | None:
        """Rows of the body's points against obstacles and rigid bodies, then of rigid bodies
        against obstacles and each other (see the module docstring)."""
        bodies, shapes, n = self.bodies, self.shapes, len(self.bodies)
        for i, b in enumerate(bodies):
            b.shape.set_pose(rigid.positions[i], rigid.rotations[i])
        # A body may close a gap by the distance its points travel in the step.
        reach = dt * rigid.speeds(bodies)
        margins = np.concatenate([np.full(len(shapes), self.margin), self.margin + reach])
        # Read every step: the obstacles' and bodies' coefficients may be changed between steps.
        mu = np.concatenate([self.friction, [b.friction for b in self.bodies]])
        deformable = detect(points, self._colliders, margins, radius=self.thickness)
        if self._carried is not None and len(deformable):
            body = np.maximum(deformable.index_b - len(shapes), 0)
            carried = (deformable.index_b >= len(shapes)) & self._carried[deformable.index_a, body]
            if carried.any():
                deformable = deformable.take(~carried)
        on_body = deformable.index_b >= len(shapes)
        motion = dt * shape_velocities(deformable, self._colliders)
        motion[on_body] = 0.0  # a rigid body's motion enters through G u
        # Side b of the body's contacts: minus the velocity of the rigid body's point.
        jacobian = -contact_twist_jacobian(
            deformable.frames,
            deformable.point_b,
            deformable.index_b - len(shapes),
            rigid.positions,
            n,
        )
        k = len(deformable)
        deformable, friction, motion = self._with_planes(
            positions, deformable, mu[deformable.index_b], motion
        )
        # The planes' rows read no rigid body.
        jacobian = np.vstack([jacobian, np.zeros((3 * (len(deformable) - k), 6 * n))])
        rows = ContactConstraint(
            deformable,
            self.points,
            friction=friction,
            obstacle_displacement=motion,
            thickness=self.thickness,
        )
        surface = self.surface_rows(positions) if self.surfaces else None
        if surface is not None:  # nor do the rows between pieces of the body
            rows = ContactConstraint.joined([rows, surface])
            jacobian = np.vstack([jacobian, np.zeros((3 * len(surface.contacts), 6 * n))])
        if self.rigid_surfaces:
            found = self._rigid_surface_rows(positions, rigid, reach)
            if found is not None:
                rows = ContactConstraint.joined([rows, found[0]])
                jacobian = np.vstack([jacobian, found[1]])
        pairs = self._rigid_pairs(reach)
        if len(rows.contacts) + len(pairs) == 0:
            return None
        # Rigid-rigid pairs: side b is an obstacle (index < len(shapes)) or another body.
        pair_jacobian = contact_twist_jacobian(
            pairs.frames, pairs.point_a, pairs.index_a, rigid.positions, n
        ) - contact_twist_jacobian(
            pairs.frames, pairs.point_b, pairs.index_b - len(shapes), rigid.positions, n
        )
        obstacle = pairs.index_b < len(shapes)
        obstacle_motion = np.zeros((len(pairs), 3))
        if obstacle.any():  # (none where the rigid bodies touch only each other)
            obstacle_motion[obstacle] = (
                dt
                * shape_velocities(
                    replace(pairs, index_b=np.where(obstacle, pairs.index_b, 0)), shapes
                )[obstacle]
            )
        pair_distance = -np.einsum("krj,kj->kr", pairs.frames, obstacle_motion)
        pair_distance[:, 0] += pairs.gap
        pair_friction = np.sqrt(mu[len(shapes) + pairs.index_a] * mu[pairs.index_b])
        return CoupledContact(
            rows,
            pairs,
            pair_distance.reshape(-1),
            pair_friction,
            np.vstack([jacobian, pair_jacobian]),
            len(self.points),
        )

    def _rigid_pairs(self, reach: np.ndarray) -> ContactSet:
        """Contacts of each rigid body (side a, index = body) with the obstacles and the later
        bodies (side b, index = obstacle, or len(shapes) + body)."""
        bodies, shapes, colliders = self.bodies, self.shapes, self._colliders
        found = []
        for i, body in enumerate(bodies):
            box = body.shape.bounds()
            for j in [*range(len(shapes)), *range(len(shapes) + i + 1, len(colliders))]:
                other = j - len(shapes)
                margin = self.margin + reach[i] + (reach[other] if other >= 0 else 0.0)
                bounds = colliders[j].bounds()
                if bounds is not None and (
                    np.any(box[0] > bounds[1] + margin) or np.any(bounds[0] > box[1] + margin)
                ):
                    continue
                pair = collide(body.shape, colliders[j], margin)
                k = len(pair)
                found.append(replace(pair, index_a=np.full(k, i), index_b=np.full(k, j)))
        return ContactSet.concatenate(found)


class CoupledContact(Constraint):
    """The contact rows of a step of a model with rigid bodies: the body's points against
    obstacles and rigid bodies (a ContactConstraint), then rigid bodies against obstacles and
    each other (rows with no deformable part), three rows (n, t1, t2) per contact.

    Attributes:
        contacts: all contacts; those of rigid pairs have index_a = n_points + body, so that
            contact identities (warm start) stay unique.
        friction: mu per contact.
        rigid_jacobian: G (3k, 6 n_bodies), the rows' dependence on the bodies' twists.
    """

    role = "contact"

    def __init__(
        self,
        rows: ContactConstraint,
        pairs: ContactSet,
        pair_distance: np.ndarray,
        pair_friction: np.ndarray,
        rigid_jacobian: np.ndarray,
        n_points: int,
        name: str = "contacts",
    ) -> None:
        self.name = name
        self.rows = rows
        self.contacts = ContactSet.concatenate(
            [rows.contacts, replace(pairs, index_a=pairs.index_a + n_points)]
        )
        self.friction = np.concatenate([rows.friction, pair_friction])
        self.rigid_jacobian = rigid_jacobian
        self._pair_distance = pair_distance
        self._pairs = pairs
        self._n_points = n_points

    def take(self, index: np.ndarray) -> CoupledContact:
        """The rows of the body's contacts `index` (indices into `rows`, or a boolean mask
        over them) and of every rigid pair."""
        index = np.flatnonzero(index) if np.asarray(index).dtype == bool else np.asarray(index)
        k = len(self.rows.contacts)
        own = (3 * index[:, None] + np.arange(3)).reshape(-1)
        keep = np.concatenate([own, np.arange(3 * k, self.rigid_jacobian.shape[0])])
        return CoupledContact(
            self.rows.take(index),
            self._pairs,
            self._pair_distance,
            self.friction[k:],
            self.rigid_jacobian[keep],
            self._n_points,
            self.name,
        )

    @property
    def n_rows(self) -> int:
        return 3 * len(self.contacts)

    def distance(self, x: np.ndarray) -> np.ndarray:
        """delta at the start of the step with the rigid bodies still (their motion: G u)."""
        return np.concatenate([self.rows.distance(x), self._pair_distance])

    def jacobian(self, x: np.ndarray) -> JacobianRows:
        """H of the deformable part; rigid pairs' rows are zero (node 0, weight 0)."""
        rows = self.rows.jacobian(x)
        r, m = self._pair_distance.size, rows.nodes.shape[1]
        return JacobianRows(
            np.vstack([rows.nodes, np.zeros((r, m), dtype=np.int64)]),
            np.concatenate([rows.values, np.zeros((r, m, 3))]),
        )


def _kept(found: ContactSet, keep: np.ndarray) -> ContactSet:
    """The contacts of `found` where `keep` is True."""
    return ContactSet(*(getattr(found, f.name)[keep] for f in fields(ContactSet)))
