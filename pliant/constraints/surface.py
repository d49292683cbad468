"""Contact between two pieces of one deformable body: points of one against the surface of the
other (SOFA's point-triangle proximity between two deformable collision models).

A body may hold several separate pieces (:class:`pliant.fem.body.TetBody` with
``separate=True``: a SOFA scene's fingers and the object they grasp). A :class:`SurfaceContact`
makes the points of one piece collide with the current triangles of another: each step, every
point within the alarm distance of the surface (margin plus the contact distance) gets a
contact with its closest triangle, and one with every other triangle it lies on (it projects
into it, or onto an edge of it from no further than ON_EDGE of the triangles' size beyond)
unless that triangle is in the closest one's plane: a point resting in the fold between two
faces of a dented surface touches both, as SOFA's proximity makes it, instead of rocking from
one to the other from step to step. With q = b_1 v_1 + b_2 v_2 + b_3 v_3 the closest point of
a triangle (barycentric weights b of its vertices v, themselves points carried by the body), n
its unit outward normal (the angle-weighted pseudo-normal of the edge or vertex where q lies
on one and the point is not on the triangle) and r the contact distance, the row reads the
relative point d(x) = p(x) - q(x), linear in the nodes of both pieces:

    delta_n = phi + n . (d(x) - d0),   delta_ti = t_i . (d(x) - d0),   phi = n . d0 - r,

d0 = p - q at detection, so the Jacobian spans the point's nodes (weights w) and the
triangle's (weights -b_i w_i), and the compliance H A^-1 H^T of the body couples both pieces as
it couples any two rows. The law is the other contacts': Signorini with Coulomb friction,
solved with them by :func:`pliant.constraints.friction.solve_contact`. The normal and the
weights are held over a step, as an obstacle's are.

Broad phase: the points inside the surface's bounding box grown by the alarm distance, then the
triangles whose centroid is within that distance plus the largest triangle's radius (a k-d
tree of the current centroids, scipy.spatial.cKDTree), then the exact closest point of each
such pair (:func:`pliant.geometry.collision_kernels.closest_on_triangles`): no loop over every
point and triangle.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from pliant.constraints.base import EmbeddedPoints
from pliant.errors import ContactError
from pliant.fem.material import check_friction
from pliant.geometry import collision_kernels as kernels
from pliant.geometry.collision import ContactSet

#: A point lies on a triangle whose closest point to it is on an edge when it projects no
#: further than this share of the triangles' size beyond that edge: a point resting in the fold
#: between two faces then touches both (a contact each), as SOFA's proximity gives it, rather
#: than the nearer one, which changes from step to step as the point rocks across the fold.
ON_EDGE = 1e-2


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
        self._used = np.unique(self.triangles)
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

    def detect(self, x: np.ndarray, margin: float, index_b: int, placed: dict | None = None):
        """The contacts at positions `x` of the points within `margin` + r of the surface: a
        ContactSet (index_a the point, index_b `index_b`, feature 2 x triangle, point_a the
        point, point_b the triangle's closest point) and the rows' (nodes, weights, origin d0),
        or None when no point is near. `placed`: positions of embedded points already read
        at `x`, by id (several pairs share their points), filled as they are read."""
        placed = {} if placed is None else placed
        for points in (self.points, self.vertices):
            if id(points) not in placed:
                placed[id(points)] = points.positions(x)
        p, vertices = placed[id(self.points)], placed[id(self.vertices)]
        found = self._nearest(p, vertices, margin + self.distance)
        if found is None:
            return None
        pi, ti, bary, normal, closest, gap = found
        d0 = p[pi] - closest
        k = pi.size
        contacts = ContactSet(
            pi, np.full(k, index_b, dtype=np.int64), 2 * ti, gap, normal, p[pi], closest
        )
        pn, pw = self._point_rows
        vn, vw_ = self._vertex_rows
        corners = self.triangles[ti]  # (k, 3) vertices
        nodes = np.concatenate([pn[pi], vn[corners].reshape(k, -1)], axis=1)
        weights = np.concatenate(
            [pw[pi], (-bary[:, :, None] * vw_[corners]).reshape(k, -1)], axis=1
        )
        return contacts, nodes, weights, d0

    def _nearest(
        self, p: np.ndarray, vertices: np.ndarray, reach: float, *, one_side: bool = False
    ):
        """The (point, triangle) pairs of the points `p` within `reach` of the triangles on
        `vertices` (see the module docstring): point and triangle indices, barycentric
        weights (k, 3), unit normals, closest points and gaps; None when no point is near.

        With `one_side`, a point outside the surface (in front of its closest triangle) gets
        no contact with a triangle it lies behind: that triangle is another sheet of the
        surface seen through the body (the far side of a thin wall, the ceiling of a cavity
        under a membrane), whose row would push the point into the body."""
        corners = vertices[self._used]
        lo, hi = corners.min(axis=0) - reach, corners.max(axis=0) + reach
        near = np.flatnonzero(np.all((p >= lo) & (p <= hi), axis=1))
        if near.size == 0:
            return None
        tri = np.ascontiguousarray(vertices[self.triangles])
        centre = tri.mean(axis=1)
        size = float(np.linalg.norm(tri - centre[:, None], axis=2).max())
        found = cKDTree(centre).query_ball_point(p[near], reach + size)
        count = np.array([len(f) for f in found], dtype=np.int64)
        if not count.any():
            return None
        pi = np.repeat(near, count)
        ti = np.fromiter((t for f in found for t in f), dtype=np.int64, count=int(count.sum()))
        vw, feature = kernels.closest_on_triangles(p, tri, pi, ti)
        a = tri[ti, 0]
        closest = a + vw[:, :1] * (tri[ti, 1] - a) + vw[:, 1:] * (tri[ti, 2] - a)
        offset = p[pi] - closest
        dist = np.linalg.norm(offset, axis=1)
        face = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        face /= np.linalg.norm(face, axis=1, keepdims=True)
        # On a triangle: the point projects into it, or onto one of its edges from no further
        # than ON_EDGE of its size beyond it (a point in a fold between two faces).
        beyond = np.linalg.norm(
            offset - np.einsum("ij,ij->i", offset, face[ti])[:, None] * face[ti], axis=1
        )
        on = (feature == kernels.FACE) | (
            (feature >= kernels.EDGE_AB) & (feature <= kernels.EDGE_CA) & (beyond <= ON_EDGE * size)
        )
        # Each point's closest triangle, and every other it lies on that is not in the
        # closest's plane (a flat surface's triangles would repeat its row).
        order = np.lexsort((dist, pi))
        first = np.ones(order.size, dtype=bool)
        first[1:] = pi[order[1:]] != pi[order[:-1]]
        nearest = np.empty(pi.size, dtype=np.int64)
        nearest[order] = order[np.maximum.accumulate(np.where(first, np.arange(order.size), 0))]
        level = np.einsum("ij,ij->i", face[ti], face[ti[nearest]]) > 1.0 - 1e-12
        chosen = on & ~level
        chosen[order[first]] = True
        chosen &= dist <= reach
        if not chosen.any():
            return None
        nearest_of = np.zeros(pi.size, dtype=bool)
        nearest_of[order[first]] = True
        pi, ti, vw, feature, closest, on, nearest_of = (
            pi[chosen],
            ti[chosen],
            vw[chosen],
            feature[chosen],
            closest[chosen],
            on[chosen],
            nearest_of[chosen],
        )
        bary = np.column_stack([1.0 - vw.sum(axis=1), vw])
        normal = self._normals(tri, face, ti, np.where(on, kernels.FACE, feature))
        side = np.einsum("ij,ij->i", normal, p[pi] - closest)
        if one_side:
            outside = np.zeros(len(p), dtype=bool)
            outside[pi[nearest_of]] = side[nearest_of] >= 0.0
            keep = nearest_of | ~(outside[pi] & (side < 0.0))
            if not keep.all():
                pi, ti, bary, normal, closest, side = (
                    a[keep] for a in (pi, ti, bary, normal, closest, side)
                )
        return pi, ti, bary, normal, closest, side - self.distance

    def _normals(
        self, tri: np.ndarray, face: np.ndarray, t: np.ndarray, feature: np.ndarray
    ) -> np.ndarray:
        """Unit normals of the contacts on triangles `t` at their closest `feature`: the
        triangle's where the closest point is inside it, else the angle-weighted
        pseudo-normal of its edge or vertex (Baerentzen and Aanaes 2005, as Pliant's mesh
        obstacles), so that a point level with an edge of the surface (a block on a block of
        the same width) is pushed off both faces it meets, not along one of them. `face`:
        the unit normals of all the triangles `tri`."""
        normal = face[t].copy()
        on_edge = (feature >= kernels.EDGE_AB) & (feature <= kernels.EDGE_CA)
        if on_edge.any():
            twin = self._twin[t[on_edge], feature[on_edge] - kernels.EDGE_AB]
            normal[on_edge] += np.where(twin[:, None] >= 0, face[np.maximum(twin, 0)], 0.0)
        on_vertex = feature <= kernels.VERTEX_C
        if on_vertex.any():
            corner = np.zeros((len(self.vertices), 3))
            for k in range(3):
                e1 = tri[:, (k + 1) % 3] - tri[:, k]
                e2 = tri[:, (k + 2) % 3] - tri[:, k]
                cos = np.einsum("ij,ij->i", e1, e2) / (
                    np.linalg.norm(e1, axis=1) * np.linalg.norm(e2, axis=1)
                )
                angle = np.arccos(np.clip(cos, -1.0, 1.0))
                np.add.at(corner, self.triangles[:, k], angle[:, None] * face)
            normal[on_vertex] = corner[self.triangles[t[on_vertex], feature[on_vertex]]]
        return normal / np.linalg.norm(normal, axis=1, keepdims=True)


class RigidSurfaceContact(SurfaceContact):
    """Points carried by a rigid body against the current surface triangles of the
    deformable body (SOFA's point or sphere collision model of a rigid object against a
    deformable TriangleCollisionModel).

    The points sit at fixed places `local` in the rigid body's frame; a sphere is its centre
    with its radius added to the contact distance. Each step, posed with the body at the
    step's start, they are detected as :class:`SurfaceContact`'s points are, except that a
    point in front of its closest triangle gets no contact with a triangle it lies behind
    (another sheet of the surface within reach: a thin wall's far face, a cavity's ceiling
    under a membrane, as on SOFA's BubbleMotion board; its row would push the point through
    the body). The row reads
    the relative point d = p - q as there, but p moves with the rigid body:

        delta = phi + frames (q0 - q(x)) + h G u,

    the triangle's part on its three nodes (weights -b_i, :meth:`ContactConstraint.relative`)
    and G = frames . J(p) the rigid point's velocity in the body's twist u
    (:func:`pliant.fem.rigid.contact_twist_jacobian`), coupled by the step as any contact
    with a rigid body (:class:`pliant.constraints.contact.CoupledContact`).

    Args:
        body: the rigid body (one of the model's).
        local: (k, 3) the points in the body's frame (relative to its centre of mass).
        vertices, triangles: the deformable surface, as :class:`SurfaceContact`'s.
        friction: Coulomb coefficient mu.
        distance: the contact distance r; `radius` is added to it (a sphere's centre).
        name: what to call the pair in errors.
    """

    def __init__(
        self,
        body,
        local: np.ndarray,
        vertices: EmbeddedPoints,
        triangles: np.ndarray,
        *,
        friction: float = 0.0,
        distance: float = 0.0,
        radius: float = 0.0,
        name: str = "rigid surface contact",
    ) -> None:
        local = np.asarray(local, dtype=float)
        if local.ndim != 2 or local.shape[1] != 3 or len(local) == 0:
            raise ContactError(f"{name}: local points must be a non-empty (k, 3) array")
        if not np.all(np.isfinite(local)):
            raise ContactError(f"{name}: local points must be finite")
        if not (math.isfinite(radius) and radius >= 0.0):
            raise ContactError(f"{name}: the radius must be finite and >= 0")
        # The surface checks of SurfaceContact, with the body's points standing in for the
        # colliding points (they read no node).
        stand_in = EmbeddedPoints.at_nodes(np.zeros(len(local), dtype=np.int64))
        stand_in.weights = np.zeros_like(stand_in.weights)
        super().__init__(
            stand_in,
            vertices,
            triangles,
            friction=friction,
            distance=distance + radius,
            name=name,
        )
        self.body = body
        self.local = local.copy()

    def detect_rigid(
        self, x: np.ndarray, margin: float, index_b: int, centre: np.ndarray, rotation
    ):
        """As :meth:`SurfaceContact.detect`, the points placed by the body's pose (`centre`,
        `rotation`): the ContactSet (point_a the rigid point, in the world) and the rows'
        (nodes, weights, origin) of the triangle's part, or None when no point is near."""
        p = centre + self.local @ np.asarray(rotation).T
        found = self._nearest(p, self.vertices.positions(x), margin + self.distance, one_side=True)
        if found is None:
            return None
        pi, ti, bary, normal, closest, gap = found
        k = pi.size
        contacts = ContactSet(
            pi, np.full(k, index_b, dtype=np.int64), 2 * ti, gap, normal, p[pi], closest
        )
        vn, vw = self._vertex_rows
        corners = self.triangles[ti]
        nodes = vn[corners].reshape(k, -1)
        weights = (-bary[:, :, None] * vw[corners]).reshape(k, -1)
        return contacts, nodes, weights, -closest


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
