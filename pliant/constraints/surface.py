"""Contact between two pieces of one deformable body: points of one against the surface of the
other (SOFA's point-triangle proximity between two deformable collision models).

A body may hold several separate pieces (:class:`pliant.fem.body.TetBody` with
``separate=True``: a SOFA scene's fingers and the object they grasp). A :class:`SurfaceContact`
makes the points of one piece collide with the current triangles of another: each step, every
point within the alarm distance of the surface (margin plus the contact distance) gets one
contact with its closest triangle. With q = b_1 v_1 + b_2 v_2 + b_3 v_3 the closest point of
that triangle (barycentric weights b of its vertices v, themselves points carried by the body),
n the triangle's unit outward normal and r the contact distance, the row reads the relative
point d(x) = p(x) - q(x), linear in the nodes of both pieces:

    delta_n = phi + n . (d(x) - d0),   delta_ti = t_i . (d(x) - d0),   phi = n . d0 - r,

d0 = p - q at detection, so the Jacobian spans the point's nodes (weights w) and the
triangle's (weights -b_i w_i), and the compliance H K^-1 H^T of the body couples both pieces as
it couples any two rows. The law is the other contacts': Signorini with Coulomb friction,
solved with them by :func:`pliant.constraints.friction.solve_contact`. The normal and the
weights are held over a step, as an obstacle's are.

Broad phase: the points inside the surface's bounding box grown by the alarm distance, then the
exact closest triangle over a bounding-volume hierarchy of the current triangles
(:func:`pliant.geometry.collision_kernels.closest_points`), O(points log triangles).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from pliant.constraints.base import EmbeddedPoints
from pliant.errors import ContactError
from pliant.fem.material import check_friction
from pliant.geometry import collision_kernels as kernels
from pliant.geometry.collision import ContactSet

#: A vertex of the surface is sharp where one of its faces turns from its normal by more
#: than this (radians); a box's edges and corners are, a dented face is not.
SHARP = math.radians(30.0)


def _trimmed(points: EmbeddedPoints) -> tuple[np.ndarray, np.ndarray]:
    """(nodes, weights) of embedded points without the columns no point reads (at_nodes
    points are read through one node)."""
    used = np.flatnonzero(np.any(points.weights != 0.0, axis=0))
    width = int(used.max()) + 1 if used.size else 1
    return points.nodes[:, :width], points.weights[:, :width]


def body_pieces(tets: np.ndarray, n_nodes: int) -> list[np.ndarray]:
    """The nodes of each separate piece of a mesh (connected through its elements), ordered
    by their first node."""
    t = np.asarray(tets, dtype=np.int64)
    rows = np.repeat(t[:, 0], t.shape[1] - 1)
    cols = t[:, 1:].reshape(-1)
    graph = coo_matrix((np.ones(rows.size), (rows, cols)), shape=(n_nodes, n_nodes))
    count, label = connected_components(graph, directed=False)
    return [np.flatnonzero(label == c) for c in range(count)]


class SurfaceContact:
    """Points of one piece of the body against the surface triangles of another.

    Args:
        points: the colliding points (EmbeddedPoints: nodes, or points carried by elements).
        vertices: the surface's vertices, points carried by the body (EmbeddedPoints).
        triangles: (t, 3) indices into `vertices`, oriented with outward normals.
        friction: Coulomb coefficient mu of these contacts.
        distance: the contact distance r: the points touch the surface at distance r (SOFA's
            contactDistance); a contact's gap is its distance less r.
        name: what to call the pair in errors.

    ContactError where the points and the surface share a node (a piece does not touch itself
    here) or the triangles index outside the vertices.
    """

    def __init__(
        self,
        points: EmbeddedPoints,
        vertices: EmbeddedPoints,
        triangles: np.ndarray,
        *,
        friction: float = 0.0,
        distance: float = 0.0,
        name: str = "surface contact",
    ) -> None:
        self.name = name
        tri = np.asarray(triangles)
        if tri.ndim != 2 or tri.shape[1] != 3 or len(tri) == 0:
            raise ContactError(
                f"{name}: triangles must be a non-empty (t, 3) array, got {tri.shape}"
            )
        if not np.issubdtype(tri.dtype, np.integer) or tri.min() < 0 or tri.max() >= len(vertices):
            raise ContactError(f"{name}: triangles must index the {len(vertices)} vertices")
        if len(points) == 0:
            raise ContactError(f"{name}: no colliding points")
        if not (points.linear and vertices.linear):
            raise ContactError(f"{name}: points and vertices must be linear in the nodes")
        if not (math.isfinite(distance) and distance >= 0.0):
            raise ContactError(f"{name}: the contact distance must be finite and >= 0")
        self.friction = float(check_friction(friction, 1)[0])
        self.distance = float(distance)
        self.points, self.vertices = points, vertices
        self.triangles = tri.astype(np.int64)
        self._point_rows = _trimmed(points)
        self._vertex_rows = _trimmed(vertices)
        own = np.unique(self._point_rows[0][self._point_rows[1] != 0.0])
        surface = np.unique(
            self._vertex_rows[0][self.triangles][self._vertex_rows[1][self.triangles] != 0.0]
        )
        shared = np.intersect1d(own, surface)
        self._twin = _twins(self.triangles)
        if shared.size:
            raise ContactError(
                f"{name}: the points and the surface share node {int(shared[0])} (and"
                f" {shared.size - 1} more): they must be separate pieces of the body"
            )

    @classmethod
    def between(
        cls, body, piece_a, piece_b, *, friction: float = 0.0, distance: float = 0.0
    ) -> SurfaceContact:
        """The colliding nodes of `piece_a` (its surface nodes that are not held) against the
        boundary triangles of `piece_b`; each piece a set of the body's node indices (one of
        :func:`body_pieces`)."""
        a = np.asarray(piece_a, dtype=np.int64)
        b = np.asarray(piece_b, dtype=np.int64)
        nodes = np.intersect1d(body.colliding_nodes(), a)
        faces = body.boundary_triangles
        faces = faces[np.all(np.isin(faces, b), axis=1)]
        if len(faces) == 0:
            raise ContactError("between: piece_b has no boundary triangle")
        used, local = np.unique(faces, return_inverse=True)
        return cls(
            EmbeddedPoints.at_nodes(nodes),
            EmbeddedPoints.at_nodes(used),
            local.reshape(-1, 3),
            friction=friction,
            distance=distance,
        )

    def detect(self, x: np.ndarray, margin: float, index_b: int):
        """The contacts at positions `x` of the points within `margin` + r of the surface: a
        ContactSet (index_a the point, index_b `index_b`, feature 2 x triangle, point_a the
        point, point_b the triangle's closest point) and the rows' (nodes, weights, origin d0),
        or None when no point is near."""
        p = self.points.positions(x)
        tri = np.ascontiguousarray(self.vertices.positions(x)[self.triangles])
        reach = margin + self.distance
        lo, hi = tri.min(axis=(0, 1)) - reach, tri.max(axis=(0, 1)) + reach
        near = np.flatnonzero(np.all((p >= lo) & (p <= hi), axis=1))
        if near.size == 0:
            return None
        dist2, closest, t, feature = kernels.closest_points(
            np.ascontiguousarray(p[near]), tri, *kernels.build_bvh(tri)
        )
        keep = dist2 <= reach * reach
        if not keep.any():
            return None
        near, closest, t, feature = near[keep], closest[keep], t[keep], feature[keep]
        a, b, c = tri[t, 0], tri[t, 1], tri[t, 2]
        # Barycentric weights of the closest point, from the triangle's Gram system.
        e1, e2, r = b - a, c - a, closest - a
        g11, g12, g22 = (np.einsum("ij,ij->i", u, v) for u, v in ((e1, e1), (e1, e2), (e2, e2)))
        r1, r2 = np.einsum("ij,ij->i", r, e1), np.einsum("ij,ij->i", r, e2)
        det = g11 * g22 - g12 * g12
        v = (g22 * r1 - g12 * r2) / det
        w = (g11 * r2 - g12 * r1) / det
        bary = np.column_stack([1.0 - v - w, v, w])
        normal = self._normals(tri, t, feature, bary)
        d0 = p[near] - closest
        gap = np.einsum("ij,ij->i", normal, d0) - self.distance
        k = near.size
        found = ContactSet(
            near.astype(np.int64),
            np.full(k, index_b, dtype=np.int64),
            2 * t.astype(np.int64),
            gap,
            normal,
            p[near],
            closest,
        )
        pn, pw = self._point_rows
        vn, vw = self._vertex_rows
        corners = self.triangles[t]  # (k, 3) vertices
        nodes = np.concatenate([pn[near], vn[corners].reshape(k, -1)], axis=1)
        weights = np.concatenate(
            [pw[near], (-bary[:, :, None] * vw[corners]).reshape(k, -1)], axis=1
        )
        return found, nodes, weights, d0

    def _normals(
        self, tri: np.ndarray, t: np.ndarray, feature: np.ndarray, bary: np.ndarray
    ) -> np.ndarray:
        """Unit normals of the contacts on triangles `t` at their closest `feature`, closest
        point `bary`: the normals of the triangle's corners interpolated (Phong's), each the
        angle-weighted normal of the surface at its vertex where the surface is smooth there;
        at a sharp vertex (a face turned by more than SHARP from it: a box's edge), the
        normal of the feature the closest point lies on (the face, the two faces of the
        edge, or the vertex's; Baerentzen and Aanaes 2005, as Pliant's mesh obstacles).

        Continuous across smooth edges, so that a point resting in the fold between two
        faces of a dented surface does not flip from one face's normal to the other's from
        step to step; exact on flat faces; and a point level with a sharp edge (a block on a
        block of the same width) is pushed off both faces it meets, not along one of them.
        """
        face = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        face /= np.linalg.norm(face, axis=1, keepdims=True)
        corner = np.zeros((len(self.vertices), 3))
        for k in range(3):
            e1 = tri[:, (k + 1) % 3] - tri[:, k]
            e2 = tri[:, (k + 2) % 3] - tri[:, k]
            cos = np.einsum("ij,ij->i", e1, e2) / (
                np.linalg.norm(e1, axis=1) * np.linalg.norm(e2, axis=1)
            )
            np.add.at(corner, self.triangles[:, k], np.arccos(np.clip(cos, -1, 1))[:, None] * face)
        corner /= np.maximum(np.linalg.norm(corner, axis=1, keepdims=True), 1e-300)
        # The least cosine between a vertex's normal and its faces'.
        least = np.ones(len(self.vertices))
        for k in range(3):
            v = self.triangles[:, k]
            np.minimum.at(least, v, np.einsum("ij,ij->i", face, corner[v]))
        smooth = least >= math.cos(SHARP)
        on = face[t]
        on_edge = (feature >= kernels.EDGE_AB) & (feature <= kernels.EDGE_CA)
        if on_edge.any():
            twin = self._twin[t[on_edge], feature[on_edge] - kernels.EDGE_AB]
            on[on_edge] += np.where(twin[:, None] >= 0, face[np.maximum(twin, 0)], 0.0)
        on_vertex = feature <= kernels.VERTEX_C
        on[on_vertex] = corner[self.triangles[t[on_vertex], feature[on_vertex]]]
        on /= np.linalg.norm(on, axis=1, keepdims=True)
        corners = self.triangles[t]  # (k, 3)
        each = np.where(smooth[corners][:, :, None], corner[corners], on[:, None, :])
        normal = np.einsum("ki,kij->kj", bary, each)
        return normal / np.linalg.norm(normal, axis=1, keepdims=True)


def _twins(triangles: np.ndarray) -> np.ndarray:
    """(t, 3) the triangle across edge k (ab, bc, ca) of each triangle, -1 where none (an open
    edge) or where the edge is not shared by exactly one other triangle in the opposite
    direction."""
    n = int(triangles.max()) + 1
    directed = np.stack([triangles, np.roll(triangles, -1, axis=1)], axis=2).reshape(-1, 2)
    keys = directed[:, 0] * n + directed[:, 1]
    order = np.argsort(keys, kind="stable")
    wanted = directed[:, 1] * n + directed[:, 0]
    at = np.clip(np.searchsorted(keys[order], wanted), 0, len(keys) - 1)
    found = keys[order[at]] == wanted
    return np.where(found, order[at] // 3, -1).reshape(-1, 3)
