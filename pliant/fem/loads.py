"""External loads on a tetrahedral body and elastic supports: nodal forces (SOFA's
ConstantForceField), surface pressure and traction (SurfacePressureForceField-like), a point
force that turns with the body (a follower force in the frame of the element carrying it),
springs to the rest shape (RestShapeSpringsForceField), springs between points carried by the
body (MeshSpringForceField on barycentrically mapped points).

A load gives nodal forces f(x, t) on groups of nodes (one node, or the three of a triangle)
and, when they depend on the positions, the groups' tangent blocks K = -df/dx. The body adds
them to its internal forces and tangent (:class:`pliant.fem.body.TetBody`, ``loads=``), so the
static and dynamic solvers take them in without knowing them. Time-varying loads scale with a
function of the time the solver passes (the start of a dynamic step, a static step's time).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy.spatial.transform import Rotation

from pliant.errors import ModelError
from pliant.mesh.locate import locate_points
from pliant.mesh.tetmesh import TetMesh

Schedule = Callable[[float], float]


def _skew(v: np.ndarray) -> np.ndarray:
    """[v]x for each row of v (k, 3) -> (k, 3, 3)."""
    out = np.zeros((*v.shape[:-1], 3, 3))
    out[..., 0, 1], out[..., 0, 2] = -v[..., 2], v[..., 1]
    out[..., 1, 0], out[..., 1, 2] = v[..., 2], -v[..., 0]
    out[..., 2, 0], out[..., 2, 1] = -v[..., 1], v[..., 0]
    return out


class Load:
    """Base of the loads: `groups` (e, k) node indices; forces per group node (e, k, 3);
    tangent blocks (e, 3k, 3k), or None for a load that does not depend on the positions."""

    groups: np.ndarray
    schedule: Schedule | None = None
    #: its groups may join nodes of different elements: the body widens its stiffness
    #: pattern to hold them (otherwise a group outside one element is an error).
    spans_elements: bool = False

    def scale(self, time: float) -> float:
        return 1.0 if self.schedule is None else float(self.schedule(time))

    def group_forces(self, x: np.ndarray, time: float) -> np.ndarray:
        raise NotImplementedError

    def group_tangents(self, x: np.ndarray, time: float) -> np.ndarray | None:
        return None

    def forces(self, x: np.ndarray, time: float = 0.0) -> np.ndarray:
        """Nodal forces (n, 3) at positions x and time t."""
        out = np.zeros_like(x)
        np.add.at(out, self.groups, self.group_forces(x, time))
        return out


def _check_nodes(nodes, what: str) -> np.ndarray:
    idx = np.asarray(nodes, dtype=np.int64)
    if idx.size == 0 or idx.min() < 0:
        raise ModelError(f"{what}: give non-negative node indices")
    return idx


class NodalForces(Load):
    """Forces on nodes, constant or scaled in time (SOFA's ConstantForceField).

    Args:
        nodes: (k,) node indices.
        forces: (k, 3) forces, or one (3,) force on every node.
        schedule: f(t) scaling the forces (None: constant).
    """

    def __init__(self, nodes, forces, *, schedule: Schedule | None = None) -> None:
        idx = _check_nodes(nodes, "NodalForces")
        values = np.broadcast_to(np.asarray(forces, dtype=float), (idx.size, 3)).copy()
        if not np.all(np.isfinite(values)):
            raise ModelError("NodalForces: forces must be finite")
        self.groups = idx.reshape(-1, 1)
        self.values = values
        self.schedule = schedule

    def group_forces(self, x, time):
        return self.scale(time) * self.values[:, None, :]


class SurfaceTraction(Load):
    """A traction (force per area of the rest surface) on triangles, a dead load: each node
    of a triangle of rest area A carries A t / 3 (exact for a uniform traction on linear
    triangles).

    Args:
        triangles: (t, 3) node indices of faces of the body.
        rest_positions: the body's rest positions (for the areas).
        traction: (3,) force per area.
        schedule: f(t) scaling the traction.
    """

    def __init__(
        self, triangles, rest_positions, traction, *, schedule: Schedule | None = None
    ) -> None:
        tri = _check_nodes(triangles, "SurfaceTraction").reshape(-1, 3)
        p = np.asarray(rest_positions, dtype=float)[tri]
        area = 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)
        self.groups = tri
        self.values = area[:, None, None] / 3.0 * np.asarray(traction, dtype=float)[None, None]
        self.schedule = schedule

    def group_forces(self, x, time):
        return self.scale(time) * np.broadcast_to(self.values, (*self.groups.shape, 3))


class SurfacePressure(Load):
    """A pressure on triangles that follows the surface (a follower load): a triangle of
    current area A and unit normal n (right-hand rule) carries p A n, a third on each node,
    f_a = p/6 (x1 - x0) x (x2 - x0). On a closed surface these are p dV/dx: the force of a
    cavity at pressure p (:class:`pliant.constraints.cavity.CavityActuator`).

    Its tangent K_ab = -df_a/dx_b = -p/6 d((x1 - x0) x (x2 - x0))/dx_b is not symmetric for an
    open surface (it is for a closed one, summed over the triangles): the body assembles its
    symmetric part, the forces stay exact.

    Args:
        triangles: (t, 3) node indices of faces of the body, normals where the pressure pushes.
        pressure: p (force per area).
        schedule: f(t) scaling the pressure.
    """

    def __init__(self, triangles, pressure: float, *, schedule: Schedule | None = None) -> None:
        self.groups = _check_nodes(triangles, "SurfacePressure").reshape(-1, 3)
        self.pressure = float(pressure)
        if not np.isfinite(self.pressure):
            raise ModelError("SurfacePressure: the pressure must be finite")
        self.schedule = schedule

    def group_forces(self, x, time):
        p = x[self.groups]
        area_normal = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])  # 2 A n
        force = self.scale(time) * self.pressure / 6.0 * area_normal
        return np.repeat(force[:, None, :], 3, axis=1)

    def group_tangents(self, x, time):
        p = x[self.groups]
        e1, e2 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
        # d(e1 x e2) = [e2 - e1]x dx0 - [e2]x dx1 + [e1]x dx2.
        d = np.stack([_skew(e2 - e1), -_skew(e2), _skew(e1)], axis=1)  # (t, 3 nodes, 3, 3)
        coef = -self.scale(time) * self.pressure / 6.0
        blocks = np.zeros((len(self.groups), 9, 9))
        for b in range(3):
            for a in range(3):
                blocks[:, 3 * a : 3 * a + 3, 3 * b : 3 * b + 3] = coef * d[:, b]
        return blocks


class FollowerForce(Load):
    """A force at a point carried by the body, given at rest and turning with the body: the
    point is embedded in the element that contains it (barycentric weights w_a), and the force
    turns with that element's frame, f(x) = Q(x) Q(X)^T f0, Q the orthonormal frame of its
    edges (first axis along x1 - x0, third normal to the plane of x0, x1, x2: the frame of
    SOFA's "large" rotation). Node a of the element carries w_a f.

    The frame is the element's rigid rotation up to its strain (exactly the polar rotation
    when the element turns rigidly), so the force follows a rigid motion of the body exactly.
    Its tangent K_ab = -w_a df/dx_b (closed form below) is not symmetric: the body assembles
    its symmetric part, the forces stay exact.

    Args:
        mesh: the body's mesh (its rest positions).
        point: (3,) where the force acts, in or on the mesh.
        force: (3,) the force at rest, in world coordinates.
        schedule: f(t) scaling the force.
    """

    def __init__(self, mesh: TetMesh, point, force, *, schedule: Schedule | None = None) -> None:
        element, weights = locate_points(mesh, np.asarray(point, dtype=float).reshape(1, 3))
        self.groups = mesh.tets[element].astype(np.int64)  # (1, 4); frame: its first three
        self.weights = weights[0]
        f0 = np.asarray(force, dtype=float).reshape(-1)
        if f0.shape != (3,) or not np.all(np.isfinite(f0)):
            raise ModelError(f"FollowerForce: the force must be a finite 3-vector, got {force!r}")
        # The force's components in the element's rest frame.
        self.components = _edge_frame(mesh.points[self.groups[0]])[0].T @ f0
        self.schedule = schedule

    def direction(self, x: np.ndarray) -> np.ndarray:
        """f(x) / scale: Q(x) g, g the rest components."""
        return _edge_frame(x[self.groups[0]])[0] @ self.components

    def group_forces(self, x, time):
        force = self.scale(time) * self.direction(x)
        return (self.weights[:, None] * force)[None]

    def group_tangents(self, x, time):
        # With a = x1 - x0, b = x2 - x0, c = a x b: e1 = a/|a|, e3 = c/|c|, e2 = e3 x e1, and
        # f = g1 e1 + g2 e2 + g3 e3. Then de1 = P1 da / |a|, de3 = P3 dc / |c| (P = I - e e^T),
        # dc = -[b]x da + [a]x db, de2 = -[e1]x de3 + [e3]x de1, so
        # df = (g1 I + g2 [e3]x) de1 + (g3 I - g2 [e1]x) de3 = A1 da + A3 dc with
        # A1 = (g1 I + g2 [e3]x) P1 / |a|, A3 = (g3 I - g2 [e1]x) P3 / |c|:
        # df/dx1 = A1 - A3 [b]x, df/dx2 = A3 [a]x, df/dx0 = -(df/dx1 + df/dx2).
        frame, a, b = _edge_frame(x[self.groups[0]])
        e1, e3 = frame[:, 0], frame[:, 2]
        g1, g2, g3 = self.scale(time) * self.components
        c = np.cross(a, b)
        eye = np.eye(3)
        a1 = (g1 * eye + g2 * _skew(e3)) @ (eye - np.outer(e1, e1)) / np.linalg.norm(a)
        a3 = (g3 * eye - g2 * _skew(e1)) @ (eye - np.outer(e3, e3)) / np.linalg.norm(c)
        d1 = a1 - a3 @ _skew(b)
        d2 = a3 @ _skew(a)
        derivative = np.zeros((3, 12))  # df/dx over the element's four nodes
        derivative[:, 0:3], derivative[:, 3:6], derivative[:, 6:9] = -(d1 + d2), d1, d2
        blocks = -np.repeat(self.weights, 3)[:, None] * np.tile(derivative, (4, 1))
        return blocks[None]


def _edge_frame(p: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The orthonormal frame (columns e1, e2, e3) of nodes p0, p1, p2 (rows of p), and the
    edges a = p1 - p0, b = p2 - p0 it is built from."""
    a, b = p[1] - p[0], p[2] - p[0]
    e1 = a / np.linalg.norm(a)
    c = np.cross(a, b)
    e3 = c / np.linalg.norm(c)
    return np.column_stack([e1, np.cross(e3, e1), e3]), a, b


class RestShapeSprings(Load):
    """Springs pulling nodes back to their rest positions, f = -k (x - X) (SOFA's
    RestShapeSpringsForceField): an elastic support.

    Args:
        nodes: (k,) node indices.
        rest_positions: the body's rest positions.
        stiffness: k (force per length), one value or one per node.
    """

    def __init__(self, nodes, rest_positions, stiffness) -> None:
        name = type(self).__name__
        idx = _check_nodes(nodes, name)
        k = np.broadcast_to(np.asarray(stiffness, dtype=float), idx.shape).copy()
        if not np.all(np.isfinite(k)) or np.any(k <= 0):
            raise ModelError(f"{name}: stiffness must be finite and > 0")
        self.groups = idx.reshape(-1, 1)
        self.stiffness = k
        self.anchors = np.asarray(rest_positions, dtype=float)[idx]

    def group_forces(self, x, time):
        return (-self.stiffness[:, None] * (x[self.groups[:, 0]] - self.anchors))[:, None, :]

    def group_tangents(self, x, time):
        return self.stiffness[:, None, None] * np.eye(3)[None]


class RotationSprings(RestShapeSprings):
    """Springs turning a rod's orientations back to their rest rotations (SOFA's angular
    RestShapeSpringsForceField on Rigid3 frames): on an orientation row holding the rotation
    vector of R, the moment -k log(R R0^T) (world axes: the rotation vector of the turn from
    rest), whatever the rest rotation R0; tangent k I, SOFA's (exact at rest).

    Args:
        nodes: (k,) orientation rows (rotation vectors: :class:`pliant.fem.rod.RodBody`'s
            rows N..2N-1).
        rest_positions: the body's rest positions (those rows' rest rotation vectors).
        stiffness: k (moment per radian), one value or one per node.
    """

    def __init__(self, nodes, rest_positions, stiffness) -> None:
        super().__init__(nodes, rest_positions, stiffness)
        self.rest = Rotation.from_rotvec(self.anchors)

    def group_forces(self, x, time):
        turn = (Rotation.from_rotvec(x[self.groups[:, 0]]) * self.rest.inv()).as_rotvec()
        return (-self.stiffness[:, None] * turn)[:, None, :]


class EmbeddedSprings(Load):
    """Linear springs between points carried by the body (SOFA's MeshSpringForceField on the
    edges of points a BarycentricMapping carries): point p = sum_a w_pa x_a over its element's
    nodes. A spring of stiffness k and rest length L between points p, q of current length
    l = |q - p| and direction u = (q - p) / l pulls with f_p = k (l - L) u = -f_q, energy
    k (l - L)^2 / 2. Each node a of a point's element carries w_pa of its force (J^T f) and
    the tangent is J^T K J, K = k [u u^T + (1 - L / l)(I - u u^T)] on the pair (p, q).

    A group is a spring's two elements (2 k nodes, possibly different elements): the body
    widens its stiffness pattern for them (``spans_elements``).

    Args:
        nodes: (p, k) each point's element nodes (weights 0 on spare slots).
        weights: (p, k) its barycentric weights.
        edges: (e, 2) pairs of point indices.
        stiffness: k, one value or one per edge (> 0).
        rest_lengths: (e,) rest lengths; default the edges' lengths at the points' positions
            on the nodes `rest_positions` (give one of the two).
        rest_positions: the body's node positions the rest lengths are measured at.
    """

    spans_elements = True

    def __init__(
        self, nodes, weights, edges, stiffness, *, rest_lengths=None, rest_positions=None
    ) -> None:
        nodes = np.asarray(nodes, dtype=np.int64)
        weights = np.asarray(weights, dtype=float)
        if nodes.ndim != 2 or weights.shape != nodes.shape or nodes.size == 0:
            raise ModelError("EmbeddedSprings: nodes and weights must be (p, k) arrays alike")
        _check_nodes(nodes, "EmbeddedSprings")
        pairs = np.asarray(edges, dtype=np.int64)
        if pairs.size == 0 or pairs.size % 2:
            raise ModelError("EmbeddedSprings: edges must be pairs of point indices")
        pairs = pairs.reshape(-1, 2)
        if pairs.min() < 0 or pairs.max() >= nodes.shape[0]:
            raise ModelError(
                f"EmbeddedSprings: edge point indices must lie in [0, {nodes.shape[0]})"
            )
        k = np.broadcast_to(np.asarray(stiffness, dtype=float), (pairs.shape[0],)).copy()
        if not np.all(np.isfinite(k)) or np.any(k <= 0):
            raise ModelError("EmbeddedSprings: stiffness must be finite and > 0")
        self.groups = np.concatenate([nodes[pairs[:, 0]], nodes[pairs[:, 1]]], axis=1)
        # Signed weights: the spring's vector q - p = sum_a c_a x_a over the group's nodes.
        self.coefficients = np.concatenate([-weights[pairs[:, 0]], weights[pairs[:, 1]]], axis=1)
        self.stiffness = k
        if (rest_lengths is None) == (rest_positions is None):
            raise ModelError("EmbeddedSprings: give rest_lengths or rest_positions")
        if rest_lengths is None:
            rest = self._vectors(np.asarray(rest_positions, dtype=float))
            rest_lengths = np.linalg.norm(rest, axis=1)
        lengths = np.broadcast_to(np.asarray(rest_lengths, dtype=float), k.shape).copy()
        if not np.all(np.isfinite(lengths)) or np.any(lengths < 0):
            raise ModelError("EmbeddedSprings: rest lengths must be finite and >= 0")
        self.rest_lengths = lengths

    def _vectors(self, x: np.ndarray) -> np.ndarray:
        """q - p of each spring (e, 3)."""
        return np.einsum("ek,ekc->ec", self.coefficients, x[self.groups])

    def energy(self, x: np.ndarray) -> float:
        """sum k (l - L)^2 / 2."""
        stretch = np.linalg.norm(self._vectors(x), axis=1) - self.rest_lengths
        return float(0.5 * np.sum(self.stiffness * stretch**2))

    def _directions(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        d = self._vectors(x)
        length = np.linalg.norm(d, axis=1)
        if np.any(length <= 0.0):
            raise ModelError("EmbeddedSprings: a spring's two points coincide (no direction)")
        return d / length[:, None], length

    def group_forces(self, x, time):
        u, length = self._directions(x)
        pull = (self.stiffness * (length - self.rest_lengths))[:, None] * u  # on p, -on q
        return -self.coefficients[:, :, None] * pull[:, None, :]

    def group_tangents(self, x, time):
        u, length = self._directions(x)
        uu = u[:, :, None] * u[:, None, :]
        ratio = (1.0 - self.rest_lengths / length)[:, None, None]
        pair = self.stiffness[:, None, None] * (uu + ratio * (np.eye(3)[None] - uu))
        c = self.coefficients
        blocks = c[:, :, None, None, None] * c[:, None, :, None, None] * pair[:, None, None]
        m = c.shape[1]  # (e, a, b, 3, 3) -> (e, 3 m, 3 m)
        return blocks.transpose(0, 1, 3, 2, 4).reshape(-1, 3 * m, 3 * m)


class LoadAssembly:
    """A load's groups placed in a body's free DoFs and stiffness pattern (built once)."""

    def __init__(self, load: Load, n_nodes: int, free_index: np.ndarray, pattern) -> None:
        self.load = load
        groups = load.groups
        if groups.max() >= n_nodes:
            raise ModelError(f"load node indices must lie in [0, {n_nodes})")
        k3 = 3 * groups.shape[1]
        dofs = (3 * groups[:, :, None] + np.arange(3)).reshape(-1, k3)
        self.free_dofs = free_index[dofs]
        self.to_free, self.valid, self.positions = pattern.place(
            self.free_dofs, "a load couples nodes that share no tetrahedron (use mesh faces)"
        )

    def tangents(self, x: np.ndarray, time: float) -> np.ndarray | None:
        """The symmetric part of the load's tangent blocks, or None."""
        blocks = self.load.group_tangents(x, time)
        return None if blocks is None else 0.5 * (blocks + blocks.transpose(0, 2, 1))

    def add_to_data(self, blocks: np.ndarray, data: np.ndarray) -> None:
        data += np.bincount(self.positions, weights=blocks[self.valid], minlength=data.size)

    def matvec(self, blocks: np.ndarray, u: np.ndarray) -> np.ndarray:
        local = np.where(self.free_dofs[:, :, None] >= 0, u[self.free_dofs], 0.0)
        return self.to_free @ np.einsum("trc,tck->trk", blocks, local).reshape(-1, u.shape[1])
