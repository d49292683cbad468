"""Collision shapes with signed distances, and the detection of contacts.

Every shape answers the signed-distance query phi(p) (< 0 inside), the outward normal n(p) and
the closest surface point c(p), so that p = c + phi n. Queries are made in the shape's frame:
a shape has a pose (position x, rotation R: shape frame -> world) and a twist (linear and
angular velocity) that kinematic obstacles and rigid bodies update every step.

Detection (`detect`) gives every query point within `margin` of a shape as one contact: the
gap phi, the normal n (out of the shape, towards the point), a tangent frame (t1, t2) with
t2 = n x t1, and the contact point on the shape. Rigid-rigid pairs (`collide`) reuse the same
query: a sphere's centre, or a capsule's end centres, or the corners of a box, or the vertices
of a mesh, are queried against the other shape's distance, less their radius; a BoxUnion (a
maze's floor and walls) is met box by box.

Broad phase: each bounded shape keeps only the query points inside its bounding box grown by
the margin, found either by testing every point against that box or by a ball query in a k-d
tree (scipy.spatial.cKDTree) of the points. The test costs O(points) per shape, the tree
O(points log points) once and then O(hits) per shape; "auto" picks the tree from
`_TREE_MIN_SHAPES` bounded shapes on. The primitives (plane, sphere, box, capsule) are met in
one compiled pass per shape, box test included (collision_kernels.primitive_contacts), the plain
definitions below being its reference. Measured on 10k points spread in a 100 mm cube with
primitives and meshes of 1-6 mm (times per call, box test / tree; the 2-core machine shared
with another job): 8 shapes 10.3 / 9.7 ms, 16 shapes 7.6 / 7.1 ms, 64 shapes 49 / 23 ms,
256 shapes 115 / 35 ms (NumPy primitives in the same conditions: 11.3 / 8.6, 9.6 / 12.8,
64 / 35, 256 / 112 ms).

Triangle meshes: exact closest point over a bounding-volume hierarchy compiled with numba, the
sign from the angle-weighted pseudo-normal of the closest feature (face, edge or vertex;
Baerentzen and Aanaes, IEEE TVCG 11(3), 2005), which is exact for closed oriented meshes. It is
used rather than trimesh.proximity.signed_distance: for 10k points against a 1280-triangle
sphere it takes 12 ms (points near the surface, the contact case; 30 ms for points spread
through the bounding box) against 0.95 s for trimesh, whose sign needs ray tests; and it adds
no dependency.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Sequence
from dataclasses import dataclass, replace
from dataclasses import fields as dataclass_fields
from functools import cached_property

import numpy as np
from scipy.spatial import cKDTree

from pliant.errors import ContactError
from pliant.geometry import collision_kernels as kernels
from pliant.geometry.rotation import check_rotation

_TREE_MIN_SHAPES = 12
_NO_BOUND = (np.full(3, -np.inf), np.full(3, np.inf))


def _vector(value, name: str) -> np.ndarray:
    v = np.asarray(value, dtype=float).reshape(-1)
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise ContactError(f"{name} must be a finite 3-vector, got {np.asarray(value).tolist()}")
    return v


def _positive(value: float, name: str) -> float:
    v = float(value)
    if not (np.isfinite(v) and v > 0.0):
        raise ContactError(f"{name} must be finite and > 0, got {value!r}")
    return v


def _query_points(points: np.ndarray) -> np.ndarray:
    p = np.asarray(points, dtype=float)
    if p.ndim != 2 or p.shape[1] != 3:
        raise ContactError(f"query points must be a (k, 3) array, got shape {p.shape}")
    if not np.all(np.isfinite(p)):
        raise ContactError("query points must be finite")
    return p


def _rotate(vectors: np.ndarray, rotation: np.ndarray) -> np.ndarray:
    """rotation @ v for each row v, written out so that each result depends on its own row
    only (a BLAS product may round a row differently depending on the batch it is in)."""
    x, y, z = vectors[:, 0:1], vectors[:, 1:2], vectors[:, 2:3]
    return x * rotation[:, 0] + y * rotation[:, 1] + z * rotation[:, 2]


def _rotate_each(vectors: np.ndarray, rotations: np.ndarray) -> np.ndarray:
    """`_rotate` of each (k, 3) array of `vectors` (m, k, 3) by its rotation (m, 3, 3)."""
    x, y, z = vectors[..., 0:1], vectors[..., 1:2], vectors[..., 2:3]
    return (
        x * rotations[:, None, :, 0] + y * rotations[:, None, :, 1] + z * rotations[:, None, :, 2]
    )


def _box_distance(p: np.ndarray, h: np.ndarray):
    """(gap, normal, closest) of points p (..., 3) in a box's frame against the box of half
    extents h (broadcast to p's shape: one box, or one per leading index)."""
    h = np.broadcast_to(h, p.shape)
    q = np.abs(p) - h
    outside_length = np.linalg.norm(np.maximum(q, 0.0), axis=-1)
    outside = outside_length > 0.0
    gap = np.where(outside, outside_length, q.max(axis=-1))
    closest = np.clip(p, -h, h)
    normal = np.zeros_like(p)
    normal[outside] = (p[outside] - closest[outside]) / outside_length[outside][:, None]
    # Inside (or on the surface): the nearest face is the one of largest q.
    inside = np.nonzero(~outside)
    at = (*inside, np.argmax(q[inside], axis=-1))
    side = np.where(p[at] < 0.0, -1.0, 1.0)
    normal[at] = side
    closest[at] = side * h[at]
    return gap, normal, closest


def _box_corners(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """The 8 corners of the box [lo, hi]."""
    return np.array(
        [[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]
    )


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise a x b of (k, 3) arrays (np.cross costs ~40 us of overhead per call)."""
    return np.column_stack(
        [
            a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1],
            a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2],
            a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0],
        ]
    )


def tangent_frame(normals: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit tangents t1, t2 with (n, t1, t2) orthonormal and t2 = n x t1.

    t1 is n x e normalised, e the world axis least aligned with n, so the frame varies smoothly
    with n away from the ties where that axis changes.
    """
    n = np.asarray(normals, dtype=float).reshape(-1, 3)
    axis = np.argmin(np.abs(n), axis=1)
    e = np.zeros_like(n)
    e[np.arange(n.shape[0]), axis] = 1.0
    t1 = cross(n, e)
    t1 /= np.sqrt(np.einsum("ij,ij->i", t1, t1))[:, None]
    return t1, cross(n, t1)


@dataclass(frozen=True)
class SignedDistance:
    """Answer of a distance query for k points: p = closest + gap * normal."""

    gap: np.ndarray  # (k,) signed distance, < 0 inside
    normal: np.ndarray  # (k, 3) outward unit normal
    closest: np.ndarray  # (k, 3) closest point on the surface


class Shape(ABC):
    """A collision shape placed in the world by a pose and moving with a twist.

    Args:
        position: x, the origin of the shape frame in the world.
        rotation: R, shape frame -> world (default identity).
    """

    def __init__(self, position=(0.0, 0.0, 0.0), rotation: np.ndarray | None = None) -> None:
        self.set_pose(position, np.eye(3) if rotation is None else rotation)
        self.set_twist(np.zeros(3), np.zeros(3))

    def set_pose(self, position, rotation: np.ndarray) -> None:
        """Place the shape: world point = position + rotation @ shape point."""
        self._place(
            _vector(position, f"{type(self).__name__} position"),
            check_rotation(rotation, name=f"{type(self).__name__} rotation", error=ContactError),
        )

    def _place(self, position: np.ndarray, rotation: np.ndarray) -> None:
        """Set a checked pose (owned arrays); the bounds are those of the new pose."""
        self.position, self.rotation = position, rotation
        self._bounds: tuple[np.ndarray, np.ndarray] | None = None

    def set_twist(self, linear_velocity, angular_velocity) -> None:
        """Velocity of the shape frame's origin and angular velocity, both in the world."""
        self.linear_velocity = _vector(linear_velocity, "linear velocity")
        self.angular_velocity = _vector(angular_velocity, "angular velocity")

    def point_velocity(self, points: np.ndarray) -> np.ndarray:
        """Velocity of the shape's material points at world `points`: v + w x (p - x)."""
        w = np.broadcast_to(self.angular_velocity, points.shape)
        return self.linear_velocity + cross(w, points - self.position)

    def signed_distance(self, points: np.ndarray) -> SignedDistance:
        """phi, n and the closest point for world points (k, 3)."""
        p = _query_points(points)
        local = _rotate(p - self.position, self.rotation.T)
        gap, normal, closest = self._local_distance(local)
        return SignedDistance(
            gap, _rotate(normal, self.rotation), _rotate(closest, self.rotation) + self.position
        )

    @abstractmethod
    def _local_distance(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(phi, n, closest) for points in the shape frame."""

    def _primitive(self) -> tuple[int, np.ndarray] | None:
        """(kind, sizes) of a shape the compiled detection knows (collision_kernels.PLANE, ...),
        None for the others (meshes), detected through `_local_distance`."""
        return None

    def bounds(self) -> tuple[np.ndarray, np.ndarray] | None:
        """World axis-aligned bounding box (lower, upper), None for an unbounded shape; read
        only, and computed once per pose (a contact step asks for it several times)."""
        if self._bounds is None:
            box = self._local_box()
            if box is None:
                return None
            # The extreme corners of R [lo, hi] + x, axis by axis: each term of the row sums
            # (as _rotate adds them) takes the corner coordinate that makes it smallest or
            # largest.
            at_lo, at_hi = self.rotation * box[0], self.rotation * box[1]
            low, high = np.minimum(at_lo, at_hi), np.maximum(at_lo, at_hi)
            low = low[:, 0] + low[:, 1] + low[:, 2] + self.position
            high = high[:, 0] + high[:, 1] + high[:, 2] + self.position
            low.flags.writeable = high.flags.writeable = False
            self._bounds = (low, high)
        return self._bounds

    def bounding_radius(self) -> float:
        """Radius of a ball about the shape's origin that holds the shape (inf: unbounded)."""
        box = self._local_box()
        if box is None:
            return math.inf
        farthest = np.maximum(np.abs(box[0]), np.abs(box[1]))  # the farthest corner
        return float(np.linalg.norm(farthest[None], axis=1)[0])

    @abstractmethod
    def _local_box(self) -> tuple[np.ndarray, np.ndarray] | None:
        """Bounding box in the shape frame (None: unbounded)."""

    def samples(self) -> tuple[np.ndarray, float]:
        """Points (world) and a radius: the shape is covered, near its deepest possible contact,
        by spheres of that radius at those points (used for rigid-rigid contacts)."""
        return np.empty((0, 3)), 0.0


class Plane(Shape):
    """The half-space below a plane: phi(p) = n . (p - point) (n its outward normal, the shape
    frame's z axis).

    Args:
        normal: outward normal (any non-zero length).
        point: a point of the plane.
    """

    def __init__(self, normal=(0.0, 0.0, 1.0), point=(0.0, 0.0, 0.0)) -> None:
        n = _vector(normal, "plane normal")
        length = float(np.linalg.norm(n))
        if length == 0.0:
            raise ContactError("the plane normal must be non-zero")
        n = n / length
        t1, t2 = tangent_frame(n)
        super().__init__(point, np.column_stack([t1[0], t2[0], n]))

    @property
    def normal(self) -> np.ndarray:
        return self.rotation[:, 2].copy()

    def _local_distance(self, p):
        normal = np.zeros_like(p)
        normal[:, 2] = 1.0
        closest = p.copy()
        closest[:, 2] = 0.0
        return p[:, 2].copy(), normal, closest

    def _primitive(self):
        return kernels.PLANE, np.zeros(3)

    def _local_box(self):
        return None


class Sphere(Shape):
    """phi(p) = |p - x| - r."""

    def __init__(self, radius: float, position=(0.0, 0.0, 0.0), rotation=None) -> None:
        self.radius = _positive(radius, "sphere radius")
        super().__init__(position, rotation)

    def _local_distance(self, p):
        length = np.linalg.norm(p, axis=1)
        normal = np.zeros_like(p)
        normal[:, 2] = 1.0  # the centre itself: any direction is a closest one
        off_centre = length > 0.0
        normal[off_centre] = p[off_centre] / length[off_centre, None]
        return length - self.radius, normal, self.radius * normal

    def _primitive(self):
        return kernels.SPHERE, np.array([self.radius, 0.0, 0.0])

    def _local_box(self):
        return -np.full(3, self.radius), np.full(3, self.radius)

    def samples(self):
        return self.position[None, :].copy(), self.radius


class Box(Shape):
    """An oriented box of half extents h: with q = |p| - h (shape frame),
    phi = |max(q, 0)| outside and max_i q_i inside (the exact Euclidean signed distance)."""

    def __init__(self, half_extents, position=(0.0, 0.0, 0.0), rotation=None) -> None:
        h = _vector(half_extents, "box half extents")
        if np.any(h <= 0.0):
            raise ContactError(f"box half extents must be > 0, got {h.tolist()}")
        self.half_extents = h
        super().__init__(position, rotation)

    def _local_distance(self, p):
        return _box_distance(p, self.half_extents)

    def _primitive(self):
        return kernels.BOX, self.half_extents

    def _local_box(self):
        return -self.half_extents, self.half_extents.copy()

    def samples(self):
        corners = _box_corners(-self.half_extents, self.half_extents)
        return _rotate(corners, self.rotation) + self.position, 0.0


class Capsule(Shape):
    """A segment of half length L along the shape's z axis, swept by a sphere of radius r:
    phi(p) = |p - s(p)| - r with s(p) = (0, 0, clamp(p_z, -L, L))."""

    def __init__(
        self, radius: float, half_length: float, position=(0.0, 0.0, 0.0), rotation=None
    ) -> None:
        self.radius = _positive(radius, "capsule radius")
        self.half_length = _positive(half_length, "capsule half length")
        super().__init__(position, rotation)

    def _local_distance(self, p):
        axis_point = np.zeros_like(p)
        axis_point[:, 2] = np.clip(p[:, 2], -self.half_length, self.half_length)
        d = p - axis_point
        length = np.linalg.norm(d, axis=1)
        normal = np.zeros_like(p)
        normal[:, 0] = 1.0  # on the axis: any direction across it is a closest one
        off_axis = length > 0.0
        normal[off_axis] = d[off_axis] / length[off_axis, None]
        return length - self.radius, normal, axis_point + self.radius * normal

    def _primitive(self):
        return kernels.CAPSULE, np.array([self.radius, self.half_length, 0.0])

    def _local_box(self):
        extent = np.array([self.radius, self.radius, self.radius + self.half_length])
        return -extent, extent

    def samples(self):
        ends = np.array([[0.0, 0.0, -self.half_length], [0.0, 0.0, self.half_length]])
        return _rotate(ends, self.rotation) + self.position, self.radius


class TriangleMesh(Shape):
    """A closed, outward-oriented triangle mesh (vertices in the shape frame).

    Raises ContactError if an edge is not shared by exactly two faces of opposite orientation
    (the mesh is not closed), or if the enclosed volume is not positive (normals inwards).

    A point's side is read from the pseudo-normal of its closest feature (Baerentzen and
    Aanaes 2005), exact for a surface that does not cross itself. With ``winding=True`` it is
    read from the generalised winding number instead (inside where the faces' solid angles sum
    to more than half a sphere; Jacobson et al. 2013), which stays right where a surface
    overlaps itself (a decimated scan whose faces coincide, facing opposite ways), at a cost of
    one pass over the faces per point. With ``per_face=True`` a sphere outside the mesh touches
    each face within the margin (one contact each, :func:`collide`), not only the closest
    feature: a ball in a maze's corridor holds on its floor while a wall is nearer.
    """

    def __init__(
        self,
        vertices,
        faces,
        position=(0.0, 0.0, 0.0),
        rotation=None,
        *,
        winding: bool = False,
        per_face: bool = False,
    ) -> None:
        v, f = _checked_triangles(vertices, faces, "a triangle mesh", 4)
        self.vertices, self.faces = v.copy(), f
        self._check_closed()
        tri = v[f]
        volume = float(np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum()) / 6
        if not volume > 0.0:
            raise ContactError(
                f"the mesh encloses a volume of {volume:.6g} <= 0: its faces are oriented"
                " inwards (or it is flat); reverse their vertex order"
            )
        self.volume = volume
        self._size = float(np.linalg.norm(np.ptp(v, axis=0)))
        self._triangles = np.ascontiguousarray(tri)
        self._bvh = kernels.build_bvh(self._triangles)
        self._vertex_box = (v.min(axis=0), v.max(axis=0))
        self._pseudo_normals()
        self.winding = bool(winding)
        self.per_face = bool(per_face)
        super().__init__(position, rotation)

    def _check_closed(self) -> None:
        f = self.faces
        n = len(self.vertices)
        edges = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
        keys = edges[:, 0] * n + edges[:, 1]
        unique, counts = np.unique(keys, return_counts=True)
        if np.any(counts > 1):
            a, b = divmod(int(unique[np.argmax(counts > 1)]), n)
            raise ContactError(
                f"the mesh is not a closed oriented surface: edge ({a}, {b}) is used twice in"
                " the same direction (inconsistent orientation or a non-manifold edge)"
            )
        reverse = edges[:, 1] * n + edges[:, 0]
        missing = ~np.isin(reverse, unique)
        if np.any(missing):
            a, b = edges[np.argmax(missing)]
            raise ContactError(
                f"the mesh is not closed: edge ({a}, {b}) has no opposite face (a hole)"
            )

    def _pseudo_normals(self) -> None:
        """Angle-weighted pseudo-normals: faces, edges (sum of the two faces), vertices (sum
        of the incident faces weighted by their angle at the vertex)."""
        tri, f = self._triangles, self.faces
        face = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        area2 = np.linalg.norm(face, axis=1)
        if np.any(area2 <= 1e-14 * area2.max()):
            raise ContactError(
                f"the mesh has {int(np.sum(area2 <= 1e-14 * area2.max()))} degenerate"
                " (zero-area) faces"
            )
        face /= area2[:, None]
        vertex = np.zeros_like(self.vertices)
        for k in range(3):
            e1 = tri[:, (k + 1) % 3] - tri[:, k]
            e2 = tri[:, (k + 2) % 3] - tri[:, k]
            cos = np.einsum("ij,ij->i", e1, e2) / (
                np.linalg.norm(e1, axis=1) * np.linalg.norm(e2, axis=1)
            )
            np.add.at(vertex, f[:, k], np.arccos(np.clip(cos, -1.0, 1.0))[:, None] * face)
        n = len(self.vertices)
        # Edge k of a face joins its corners k and k + 1 (ab, bc, ca as in the kernel).
        directed = np.stack([f, np.roll(f, -1, axis=1)], axis=2).reshape(-1, 2)
        order = np.argsort(directed[:, 0] * n + directed[:, 1])
        twin_keys = directed[:, 1] * n + directed[:, 0]
        twin = order[np.searchsorted(directed[order, 0] * n + directed[order, 1], twin_keys)]
        edge = face.repeat(3, axis=0) + face[twin // 3]
        self._face_normals = face
        self._edge_normals = edge.reshape(-1, 3, 3)
        self._vertex_normals = vertex

    def _local_distance(self, p):
        dist2, closest, tri, feature = kernels.closest_points(
            np.ascontiguousarray(p), self._triangles, *self._bvh
        )
        pseudo = self._face_normals[tri].copy()
        on_vertex = feature <= kernels.VERTEX_C
        pseudo[on_vertex] = self._vertex_normals[self.faces[tri[on_vertex], feature[on_vertex]]]
        on_edge = (feature >= kernels.EDGE_AB) & (feature <= kernels.EDGE_CA)
        pseudo[on_edge] = self._edge_normals[tri[on_edge], feature[on_edge] - kernels.EDGE_AB]
        d = p - closest
        if self.winding:
            sign = np.where(self.winding_number(p) > 0.5, -1.0, 1.0)
        else:
            sign = np.where(np.einsum("ij,ij->i", d, pseudo) < 0.0, -1.0, 1.0)
        length = np.sqrt(dist2)
        gap = sign * length
        normal = pseudo / np.linalg.norm(pseudo, axis=1, keepdims=True)
        off = length > 1e-12 * self._size
        normal[off] = d[off] / gap[off, None]
        return gap, normal, closest

    def winding_number(self, p: np.ndarray) -> np.ndarray:
        """(k,) the generalised winding number of points in the shape frame: the faces' solid
        angles over 4 pi (Van Oosterom and Strackee's formula), 1 inside, 0 outside."""
        out = np.empty(len(p))
        for i, point in enumerate(np.asarray(p, dtype=float)):
            a, b, c = (self._triangles[:, k] - point for k in range(3))
            la, lb, lc = (np.linalg.norm(x, axis=1) for x in (a, b, c))
            det = np.einsum("ij,ij->i", a, np.cross(b, c))
            den = (
                la * lb * lc
                + np.einsum("ij,ij->i", a, b) * lc
                + np.einsum("ij,ij->i", a, c) * lb
                + np.einsum("ij,ij->i", b, c) * la
            )
            out[i] = np.arctan2(det, den).sum() / (2.0 * np.pi)
        return out

    def _local_box(self):
        return self._vertex_box

    def samples(self):
        return _rotate(self.vertices, self.rotation) + self.position, 0.0


class TriangleSurface(TriangleMesh):
    """An open triangle surface (a vessel's wall, a phantom with openings): a point's gap is
    its unsigned distance to the nearest face, the normal from that face to the point, so a
    point stays on the side it comes from (SOFA's proximity contact, LocalMinDistance, is so:
    distance-based, with no inside). Zero-area faces are left out.
    """

    def __init__(self, vertices, faces, position=(0.0, 0.0, 0.0), rotation=None) -> None:
        v, f = _checked_triangles(vertices, faces, "a triangle surface", 1)
        tri = v[f]
        face = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        area2 = np.linalg.norm(face, axis=1)
        keep = area2 > 1e-14 * area2.max()
        self.vertices, self.faces = v.copy(), f.astype(np.int64)[keep]
        self.volume = 0.0
        self._size = float(np.linalg.norm(np.ptp(v, axis=0)))
        self._triangles = np.ascontiguousarray(tri[keep])
        self._bvh = kernels.build_bvh(self._triangles)
        self._vertex_box = (v.min(axis=0), v.max(axis=0))
        self._face_normals = face[keep] / area2[keep, None]
        self.winding = False
        self.per_face = False
        Shape.__init__(self, position, rotation)

    def _local_distance(self, p):
        dist2, closest, tri, _ = kernels.closest_points(
            np.ascontiguousarray(p), self._triangles, *self._bvh
        )
        d = p - closest
        normal = self._face_normals[tri].copy()
        normal[np.einsum("ij,ij->i", d, normal) < 0.0] *= -1.0
        gap = np.sqrt(dist2)
        off = gap > 1e-12 * self._size
        normal[off] = d[off] / gap[off, None]
        return gap, normal, closest


def _checked_triangles(vertices, faces, what: str, least: int) -> tuple[np.ndarray, np.ndarray]:
    """(n, 3) finite float vertices and (m >= least, 3) int64 faces indexing them."""
    v = np.asarray(vertices, dtype=float)
    f = np.asarray(faces)
    if v.ndim != 2 or v.shape[1] != 3 or f.ndim != 2 or f.shape[1] != 3 or len(f) < least:
        raise ContactError(
            f"{what} needs (n, 3) vertices and (m >= {least}, 3) faces, got {v.shape} and {f.shape}"
        )
    if not np.all(np.isfinite(v)):
        raise ContactError("mesh vertices must be finite")
    if not np.issubdtype(f.dtype, np.integer) or f.min() < 0 or f.max() >= len(v):
        raise ContactError(f"faces must index the {len(v)} vertices")
    return v, f.astype(np.int64)


def _box_surface(half: np.ndarray, cell: float | None) -> tuple[np.ndarray, np.ndarray]:
    """Vertices and outward triangles of the surface of the box [-half, half], each face split
    into a grid of cells no longer than `cell` (None: two triangles a face)."""
    counts = [1 if cell is None else max(1, math.ceil(2 * h / cell)) for h in half]
    vertices, faces = [], []
    for axis in range(3):
        u, v = (axis + 1) % 3, (axis + 2) % 3
        a = np.linspace(-half[u], half[u], counts[u] + 1)
        b = np.linspace(-half[v], half[v], counts[v] + 1)
        grid = np.stack(np.meshgrid(a, b, indexing="ij"), axis=-1).reshape(-1, 2)
        i, j = np.meshgrid(np.arange(counts[u]), np.arange(counts[v]), indexing="ij")
        corner = (i * (counts[v] + 1) + j).ravel()
        cells = np.stack([corner, corner + counts[v] + 1, corner + counts[v] + 2, corner + 1], 1)
        for side in (-1.0, 1.0):
            points = np.zeros((len(grid), 3))
            points[:, axis], points[:, u], points[:, v] = side * half[axis], grid[:, 0], grid[:, 1]
            # (u, v, axis) is right-handed: the cells turn about +axis, so reverse them on -axis.
            quads = cells if side > 0 else cells[:, ::-1]
            offset = sum(len(p) for p in vertices)
            vertices.append(points)
            faces.append(offset + np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]]))
    # Merge the vertices that faces share along the box's edges (equal by construction).
    unique, index = np.unique(np.vstack(vertices), axis=0, return_inverse=True)
    return unique, index.reshape(-1)[np.vstack(faces)]


class BoxUnion(TriangleMesh):
    """A rigid assembly of boxes in one frame (a maze: a base plate and its walls).

    Its signed distance is the smallest of its boxes' (exact outside the union), and
    `collide` meets the other shape box by box, so that a ball touching a floor and a wall gets
    both contacts (a single closed mesh gives a sphere one closest point only). It is a
    TriangleMesh whose triangles are the boxes' surfaces, so that what draws or samples meshes
    takes it as it is; they also give its volume.

    Args:
        boxes: the boxes, posed in the union's frame; they may touch but must not overlap.
        position, rotation: the union's pose in the world.
        cell: the triangles' largest side (None: two triangles a face), so that a drawing's
            painter's sort occludes well.
    """

    def __init__(
        self, boxes, position=(0.0, 0.0, 0.0), rotation=None, *, cell: float | None = None
    ) -> None:
        self.boxes = list(boxes)
        if not self.boxes or not all(isinstance(b, Box) for b in self.boxes):
            raise ContactError("a BoxUnion needs one or more Box shapes")
        if cell is not None:
            cell = _positive(cell, "BoxUnion cell")
        vertices, faces, offset = [], [], 0
        for box in self.boxes:
            local, triangles = _box_surface(box.half_extents, cell)
            vertices.append(_rotate(local, box.rotation) + box.position)
            faces.append(triangles + offset)
            offset += len(local)
        self._parts = [Box(b.half_extents) for b in self.boxes]
        self._stacked = tuple(
            np.array([getattr(b, name) for b in self.boxes])
            for name in ("position", "rotation", "half_extents")
        )
        super().__init__(np.vstack(vertices), np.vstack(faces), position, rotation)

    @property
    def centroid(self) -> np.ndarray:
        """Centre of the volume in the union's frame (uniform density)."""
        volumes = np.array([np.prod(b.half_extents) for b in self.boxes])
        return volumes @ np.array([b.position for b in self.boxes]) / volumes.sum()

    def _place(self, position: np.ndarray, rotation: np.ndarray) -> None:
        super()._place(position, rotation)
        # The parts' poses follow from the union's, checked: they are placed unchecked.
        for box, part in zip(self.boxes, self._parts, strict=True):
            part._place(position + rotation @ box.position, rotation @ box.rotation)
        self._part_bounds: tuple[np.ndarray, np.ndarray] | None = None

    def part_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """(lower, upper) (boxes, 3): the bounds of the parts (`parts`), once per pose."""
        if self._part_bounds is None:
            bounds = [part.bounds() for part in self._parts]
            self._part_bounds = (np.array([b[0] for b in bounds]), np.array([b[1] for b in bounds]))
        return self._part_bounds

    def parts(self) -> list[Box]:
        """The boxes posed in the world (with the union's pose)."""
        return self._parts

    def _local_distance(self, p):
        """The nearest box's answer, every box's (Box.signed_distance) computed in one pass
        over a (boxes, points, 3) array: the same operations, element by element."""
        position, rotation, half = self._stacked
        local = _rotate_each(p[None] - position[:, None], rotation.transpose(0, 2, 1))
        gaps, normal, closest = _box_distance(local, half[:, None])
        nearest = np.argmin(gaps, axis=0)
        rows = np.arange(len(p))
        normal = _rotate_each(normal, rotation)[nearest, rows]
        closest = (_rotate_each(closest, rotation) + position[:, None])[nearest, rows]
        return gaps[nearest, rows], normal, closest


@dataclass(frozen=True)
class ContactSet:
    """k contacts between a side a (query points, or a first body) and a side b (a shape).

    Attributes:
        index_a: (k,) the query point (detect) or the first collider (collide).
        index_b: (k,) the shape or second collider.
        feature: (k,) 2 s if the sample s of a (query point, box corner, mesh vertex, ...)
            made the contact, 2 s + 1 if the sample s of b did; with index_a and index_b it
            identifies a contact across steps (warm start).
        gap: (k,) phi = n . (point_a - point_b), < 0 for a penetration.
        normal: (k, 3) unit normal out of b towards a; the tangents follow from it
            (`tangent_frame`), so that both sides of a contact agree on its frame.
        point_a: (k, 3) the contact point on a (the query point itself for detect).
        point_b: (k, 3) the contact point on b's surface.
    """

    index_a: np.ndarray
    index_b: np.ndarray
    feature: np.ndarray
    gap: np.ndarray
    normal: np.ndarray
    point_a: np.ndarray
    point_b: np.ndarray

    def __len__(self) -> int:
        return int(self.gap.shape[0])

    @property
    def keys(self) -> np.ndarray:
        """(k, 3) int64 identities (index_a, index_b, feature)."""
        return np.column_stack([self.index_a, self.index_b, self.feature]).astype(np.int64)

    @cached_property
    def frames(self) -> np.ndarray:
        """(k, 3, 3): rows n, t1, t2 of each contact, orthonormal with t2 = n x t1."""
        return kernels.tangent_frames(self.normal)

    @property
    def tangent1(self) -> np.ndarray:
        return self.frames[:, 1]

    @property
    def tangent2(self) -> np.ndarray:
        return self.frames[:, 2]

    @classmethod
    def empty(cls) -> ContactSet:
        i, v, f = np.zeros(0, dtype=np.int64), np.zeros((0, 3)), np.zeros(0)
        return cls(i, i.copy(), i.copy(), f, v, v.copy(), v.copy())

    @classmethod
    def concatenate(cls, sets: list[ContactSet]) -> ContactSet:
        if len(sets) <= 1:
            return sets[0] if sets else cls.empty()
        return cls(*(np.concatenate([getattr(s, name) for s in sets]) for name in _FIELDS))

    def take(self, index: np.ndarray) -> ContactSet:
        """The contacts `index` (indices or a boolean mask), in that order."""
        return ContactSet(*(getattr(self, name)[index] for name in _FIELDS))

    def swapped(self) -> ContactSet:
        """The same contacts seen from b: a and b exchanged, the normal reversed, features
        marked as b's (odd)."""
        return ContactSet(
            self.index_b,
            self.index_a,
            2 * (self.feature // 2) + 1 - self.feature % 2,
            self.gap,
            -self.normal,
            self.point_b,
            self.point_a,
        )


_FIELDS = tuple(f.name for f in dataclass_fields(ContactSet))


def _contacts_with_shape(
    points: np.ndarray,
    candidates: np.ndarray,
    shape: Shape,
    shape_index: int,
    margin: float,
    radius: float = 0.0,
    bounds: tuple[np.ndarray, np.ndarray] = _NO_BOUND,
) -> ContactSet:
    """Contacts of the candidate points inside `bounds` (spheres of `radius` around them) with
    one shape: the primitives in one compiled pass (collision_kernels.primitive_contacts), meshes
    through their signed distance."""
    candidates = candidates.astype(np.int64, copy=False)
    primitive = shape._primitive()
    if primitive is not None:
        rows, gap, normal, point_a, point_b = kernels.primitive_contacts(
            points, candidates, *bounds, *primitive, shape.position, shape.rotation, margin, radius
        )
        kept = candidates[rows]
    else:
        near = points[candidates]
        candidates = candidates[np.all((near >= bounds[0]) & (near <= bounds[1]), axis=1)]
        query = shape.signed_distance(points[candidates])
        gap = query.gap - radius
        keep = gap < margin
        kept, gap, normal = candidates[keep], gap[keep], query.normal[keep]
        point_a, point_b = points[kept] - radius * normal, query.closest[keep]
    index_b = np.full(kept.size, shape_index, dtype=np.int64)
    return ContactSet(kept, index_b, 2 * kept, gap, normal, point_a, point_b)


def detect(
    points: np.ndarray,
    shapes: list[Shape],
    margin: float | Sequence[float],
    *,
    radius: float = 0.0,
    broad_phase: str = "auto",
) -> ContactSet:
    """Contacts of query points (e.g. surface nodes of a deformable body) with shapes.

    The points are balls of `radius` (0: points; a rod's centreline nodes: its radius). Every
    (point, shape) pair with gap = phi - radius < margin (one for all shapes, or one per shape)
    is one contact, sorted by shape then point; point_a is where the ball meets the normal,
    feature is 2 x point index. `broad_phase`: "mask" (bounding-box test of every point per
    shape), "tree" (k-d tree of the points, ball query per shape) or "auto" (see the module
    docstring).
    """
    p = _query_points(points)
    margins = np.asarray(margin, dtype=float).reshape(-1)
    radius = float(radius)
    if margins.size not in (1, len(shapes)):
        raise ContactError(f"expected 1 or {len(shapes)} margins, got {margins.size}")
    if not np.all(np.isfinite(margins) & (margins >= 0.0)):
        raise ContactError(f"the margin must be finite and >= 0, got {margin!r}")
    if not (np.isfinite(radius) and radius >= 0.0):
        raise ContactError(f"the query points' radius must be finite and >= 0, got {radius!r}")
    if broad_phase not in ("auto", "mask", "tree"):
        raise ContactError(f"broad_phase must be 'auto', 'mask' or 'tree', got {broad_phase!r}")
    if len(p) == 0:
        return ContactSet.empty()
    margins = margins.tolist() * len(shapes) if margins.size == 1 else margins.tolist()
    boxes = [shape.bounds() for shape in shapes]
    n_bounded = sum(b is not None for b in boxes)
    use_tree = broad_phase == "tree" or (broad_phase == "auto" and n_bounded >= _TREE_MIN_SHAPES)
    tree = cKDTree(p) if use_tree and n_bounded else None
    every = np.arange(len(p))
    found = []
    for j, (shape, box) in enumerate(zip(shapes, boxes, strict=True)):
        bounds, candidates = _NO_BOUND, every
        if box is not None:
            grown = margins[j] + radius
            bounds = (box[0] - grown, box[1] + grown)
            if tree is not None:  # (the mask is the compiled pass's box test)
                lo, hi = bounds
                near = tree.query_ball_point(0.5 * (lo + hi), 0.5 * np.linalg.norm(hi - lo))
                candidates = np.sort(np.asarray(near, dtype=np.int64))
        if candidates.size:
            found.append(_contacts_with_shape(p, candidates, shape, j, margins[j], radius, bounds))
    return ContactSet.concatenate(found)


def collide(shape_a: Shape, shape_b: Shape, margin: float) -> ContactSet:
    """Contacts between two shapes (index_a = index_b = 0; the caller sets the colliders).

    A sphere is exact against every shape: its centre is queried against the other one, less
    its radius (sphere-plane, sphere-sphere, sphere-box, sphere-capsule, sphere-mesh). Other
    pairs query the samples of each shape against the other: box corners (box-plane exact;
    box-box and box-mesh miss edge-edge contacts), capsule end spheres (exact on a plane), mesh
    vertices. A BoxUnion meets the other shape box by box.
    """
    if isinstance(shape_b, BoxUnion):
        return _collide_parts(shape_a, shape_b, margin)
    if isinstance(shape_a, BoxUnion):
        return collide(shape_b, shape_a, margin).swapped()
    if isinstance(shape_b, Sphere) and not isinstance(shape_a, Sphere):
        return collide(shape_b, shape_a, margin).swapped()
    if isinstance(shape_a, Sphere) and isinstance(shape_b, TriangleMesh) and shape_b.per_face:
        found = _sphere_faces(shape_a, shape_b, margin)
        if found is not None:
            return found
    sides = [(shape_a, shape_b, False)]
    if not isinstance(shape_a, Sphere):
        sides.append((shape_b, shape_a, True))
    found = []
    for first, second, swap in sides:
        samples, radius = first.samples()
        box = second.bounds()
        candidates = np.arange(len(samples))
        if box is not None:
            lo, hi = box[0] - margin - radius, box[1] + margin + radius
            candidates = np.flatnonzero(np.all((samples >= lo) & (samples <= hi), axis=1))
        if candidates.size == 0:
            continue
        contacts = _contacts_with_shape(samples, candidates, second, 0, margin, radius)
        contacts = replace(contacts, index_a=np.zeros(len(contacts), dtype=np.int64))
        found.append(contacts.swapped() if swap else contacts)
    return ContactSet.concatenate(found)


def _sphere_faces(sphere: Sphere, mesh: TriangleMesh, margin: float) -> ContactSet | None:
    """Contacts of a sphere outside a mesh with each face whose closest point is within the
    margin, the sphere on the face's outer side (faces meeting at one closest point, an edge
    or a vertex, give one contact);
    feature 2 f + 1 for face f. None where the centre is inside the mesh (the closest
    feature answers then)."""
    centre = sphere.position
    if mesh.signed_distance(centre[None]).gap[0] <= 0.0:
        return None
    q = (centre - mesh.position) @ mesh.rotation
    closest = _closest_on_triangles(q, mesh._triangles)
    offset = q - closest
    distance = np.linalg.norm(offset, axis=1)
    tri = mesh._triangles
    outer = np.einsum("ij,ij->i", offset, np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]))
    near = np.flatnonzero((distance - sphere.radius < margin) & (outer > 0.0))
    if near.size == 0:
        return ContactSet.concatenate([])
    _, first = np.unique(np.round(closest[near] / (1e-9 * mesh._size)), axis=0, return_index=True)
    near = near[np.sort(first)]
    normal = (offset[near] / distance[near, None]) @ mesh.rotation.T
    point_b = closest[near] @ mesh.rotation.T + mesh.position
    k = near.size
    return ContactSet(
        np.zeros(k, dtype=np.int64),
        np.zeros(k, dtype=np.int64),
        2 * near + 1,
        distance[near] - sphere.radius,
        normal,
        centre - sphere.radius * normal,
        point_b,
    )


def _closest_on_triangles(p: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """(m, 3) closest point to p on each triangle (Ericson, Real-Time Collision Detection 5.1.5)."""
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    ab, ac, ap = b - a, c - a, p - a
    d1, d2 = np.einsum("ij,ij->i", ab, ap), np.einsum("ij,ij->i", ac, ap)
    bp, cp = p - b, p - c
    d3, d4 = np.einsum("ij,ij->i", ab, bp), np.einsum("ij,ij->i", ac, bp)
    d5, d6 = np.einsum("ij,ij->i", ab, cp), np.einsum("ij,ij->i", ac, cp)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    with np.errstate(divide="ignore", invalid="ignore"):
        denom = 1.0 / (va + vb + vc)
        v, w = vb * denom, vc * denom
        out = a + ab * v[:, None] + ac * w[:, None]  # inside the face
        t_ab = d1 / (d1 - d3)
        t_ac = d2 / (d2 - d6)
        t_bc = (d4 - d3) / ((d4 - d3) + (d5 - d6))
    cases = [
        ((d1 <= 0) & (d2 <= 0), a),
        ((d3 >= 0) & (d4 <= d3), b),
        ((vc <= 0) & (d1 >= 0) & (d3 <= 0), a + ab * t_ab[:, None]),
        ((d6 >= 0) & (d5 <= d6), c),
        ((vb <= 0) & (d2 >= 0) & (d6 <= 0), a + ac * t_ac[:, None]),
        ((va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0), b + (c - b) * t_bc[:, None]),
    ]
    done = np.zeros(len(tri), dtype=bool)
    for mask, point in cases:
        pick = mask & ~done
        out[pick] = point[pick]
        done |= pick
    return out


def _collide_parts(shape_a: Shape, union: BoxUnion, margin: float) -> ContactSet:
    """Contacts of a shape with each box of a union whose bounding box, grown by the margin,
    meets the shape's; the features are renumbered so that a contact's identity names its box
    too (sample s of box j counts as sample j * n + s, n bounding every box's and shape_a's
    samples; the parity, a's or b's sample, is kept)."""
    n = max(8, len(shape_a.samples()[0]))
    reach = shape_a.bounds()
    parts = union.parts()
    near = range(len(parts))
    if reach is not None:
        lo, hi = union.part_bounds()
        apart = np.any(lo - margin > reach[1], axis=1) | np.any(reach[0] - margin > hi, axis=1)
        near = np.flatnonzero(~apart).tolist()
    found = []
    for j in near:
        pair = collide(shape_a, parts[j], margin)
        feature = 2 * (j * n + pair.feature // 2) + pair.feature % 2
        found.append(replace(pair, feature=feature))
    return ContactSet.concatenate(found)


def shape_velocities(contacts: ContactSet, shapes: list[Shape]) -> np.ndarray:
    """(k, 3) velocity of each contact point on its shape (moving obstacles).

    Times the step h it is the obstacle's displacement over the step, to give
    ContactConstraint(obstacle_displacement=...).
    """
    velocity = np.zeros((len(contacts), 3))
    for j in np.unique(contacts.index_b):
        shape = shapes[int(j)]
        if shape.linear_velocity.any() or shape.angular_velocity.any():  # else still: 0
            rows = contacts.index_b == j
            velocity[rows] = shape.point_velocity(contacts.point_b[rows])
    return velocity
