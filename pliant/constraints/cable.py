"""Cable actuator (SoftRobots' CableConstraint)."""

from __future__ import annotations

import numpy as np
from numba import njit

from pliant.constraints.base import Actuator, EmbeddedPoints, JacobianRows, PointRowForm
from pliant.errors import ConstraintError


class CableActuator(Actuator):
    """A cable through points of the body, pulled from a point fixed in space.

    delta = L0 - L(x), the cable's shortening, with L the length of the polyline
    pull point -> p_0 -> p_1 -> ... -> p_{k-1}; lambda >= 0 is the tension. The generalised
    force on the body is H^T lambda = -lambda dL/dx.

    Args:
        points: where the cable passes, embedded in the body (k, ...).
        pull_point: fixed point the cable is pulled from; None makes the first point the
            anchor of the polyline (no pull point, as SoftRobots' hasPullPoint=False).
        rest_positions: positions of the body at rest, to define L0.
        Other keywords: see :class:`Actuator` (cables pull: min_force defaults to 0).
    """

    def __init__(
        self,
        points: EmbeddedPoints,
        rest_positions: np.ndarray,
        *,
        pull_point: np.ndarray | None = None,
        name: str = "cable",
        **bounds,
    ) -> None:
        super().__init__(name=name, **bounds)
        self.points = points
        self.pull_point = (
            None if pull_point is None else np.asarray(pull_point, dtype=float).reshape(3)
        )
        if len(points) + (self.pull_point is not None) < 2:
            raise ConstraintError(
                f"{name}: a cable needs at least two points (or a point and a pull point)"
            )
        self.rest_length = self.length(rest_positions)
        if not self.rest_length > 0:
            raise ConstraintError(f"{name}: the cable has zero rest length")

    def _polyline(self, x: np.ndarray) -> np.ndarray:
        p = self.points.positions(x)
        return p if self.pull_point is None else np.vstack([self.pull_point, p])

    def length(self, x: np.ndarray) -> float:
        return float(np.linalg.norm(np.diff(self._polyline(x), axis=0), axis=1).sum())

    def distance(self, x: np.ndarray) -> np.ndarray:
        return np.array([self.rest_length - self.length(x)])

    def point_gradients(self, x: np.ndarray) -> np.ndarray:
        """(k, 3) d delta / d p_j for the cable's embedded points p_j."""
        poly = self._polyline(x)
        seg = np.diff(poly, axis=0)
        norm = np.linalg.norm(seg, axis=1, keepdims=True)
        unit = np.divide(seg, norm, out=np.zeros_like(seg), where=norm > 0)
        # dL/dp_j = u_{j-1} - u_j over the polyline's vertices.
        dl = np.zeros_like(poly)
        dl[1:] += unit
        dl[:-1] -= unit
        if self.pull_point is not None:
            dl = dl[1:]
        return -dl

    def jacobian(self, x: np.ndarray) -> JacobianRows:
        # d delta / d node, (k, 4, 3)
        grad = self.point_gradients(x)[:, None, :] * self.points.weights[:, :, None]
        return JacobianRows(self.points.nodes.reshape(1, -1), grad.reshape(1, -1, 3))

    @classmethod
    def bundle(cls, cables: list[CableActuator]) -> CableBundle:
        return CableBundle(cables)

    def point_row_form(self) -> PointRowForm:
        """One row whose point gradients follow the cable's path (its bundle's
        ``point_gradients``)."""
        return PointRowForm(self.points, None)

    def augmented_nodes(self) -> np.ndarray | None:
        """The cable's nodes when its shortening is held (displacement mode)."""
        return np.unique(self.points.nodes) if self.mode == "displacement" else None

    def polyline(self, x: np.ndarray) -> np.ndarray:
        """Current cable path, for drawing."""
        return self._polyline(x)


class CableBundle:
    """Several cables evaluated together: one pass of array operations for all their rows.

    Same distances and Jacobians as the cables one by one (the tests check it); the model
    uses a bundle for every run of consecutive cables, which matters for the 8-cable Trunk.
    """

    role = "actuator"

    def __init__(self, cables: list[CableActuator]) -> None:
        self.cables = cables
        self.n_rows = len(cables)
        self._nodes = np.concatenate([c.points.nodes for c in cables])
        self._weights = np.concatenate([c.points.weights for c in cables])
        pulls = [c.pull_point for c in cables if c.pull_point is not None]
        self._pulls = np.array(pulls).reshape(-1, 3)
        n_points = len(self._nodes)
        # Vertices of every polyline, as indices into [embedded points; pull points].
        starts, ends, owner = [], [], []
        offset, pull_index = 0, n_points
        for i, c in enumerate(cables):
            k = len(c.points)
            verts = list(range(offset, offset + k))
            if c.pull_point is not None:
                verts = [pull_index, *verts]
                pull_index += 1
            starts += verts[:-1]
            ends += verts[1:]
            owner += [i] * (len(verts) - 1)
            offset += k
        self._starts = np.array(starts, dtype=np.int64)
        self._ends = np.array(ends, dtype=np.int64)
        self._owner = np.array(owner, dtype=np.int64)
        self._rest = np.array([c.rest_length for c in cables])
        per = self._nodes.shape[1]  # nodes per point: 4 in tetrahedra, 8 in hexahedra
        width = max(per * len(c.points) for c in cables)
        self._cols = np.zeros((self.n_rows, width), dtype=np.int64)
        self._valid = np.zeros((self.n_rows, width), dtype=bool)
        offset = 0
        for i, c in enumerate(cables):
            k = per * len(c.points)
            self._cols[i, :k] = np.arange(per * offset, per * offset + k)
            self._valid[i, :k] = True
            offset += len(c.points)
        self._row_nodes = np.where(self._valid, self._nodes.reshape(-1)[self._cols], 0)

    def distance(self, x: np.ndarray) -> np.ndarray:
        return self._rows(x)[0]

    def point_gradients(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Shortenings (rows,) and d delta / d p (P, 3) for the cables' embedded points, in
        the order of the cables and of their points."""
        return _bundle_points(*self._arguments(x))

    def _rows(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return _bundle_rows(*self._arguments(x))

    def _arguments(self, x: np.ndarray) -> tuple:
        return (
            np.ascontiguousarray(x, dtype=np.float64),
            self._nodes,
            self._weights,
            self._pulls,
            self._starts,
            self._ends,
            self._owner,
            self._rest,
        )

    def distance_and_jacobian(self, x: np.ndarray) -> tuple[np.ndarray, JacobianRows]:
        delta, grad = self._rows(x)
        values = np.where(self._valid[:, :, None], grad.reshape(-1, 3)[self._cols], 0.0)
        return delta, JacobianRows(self._row_nodes, values)

    def jacobian(self, x: np.ndarray) -> JacobianRows:
        return self.distance_and_jacobian(x)[1]

    def geometric_pairs(self) -> tuple[np.ndarray, np.ndarray]:
        """Node pairs (i, j) coupled by the cables' geometric stiffness, one per entry of
        :meth:`geometric_stiffness`: for each segment, each pair of its embedded end points
        and each pair of their element nodes (a pull point carries no node)."""
        self._geometry_entries()
        return self._g_node_i, self._g_node_j

    def geometric_stiffness(self, x: np.ndarray, tension: np.ndarray) -> np.ndarray:
        """(E, 3, 3) blocks of -d(H^T lambda)/dx = sum_s lambda_s d^2 L/dx^2 at `x` for the
        cable tensions `tension` (one per cable), on the pairs of :meth:`geometric_pairs`.

        A segment of length l and direction u has d^2 l / dp^2 = (I - u u^T) / l for its
        end-point difference; a taut cable (lambda >= 0) adds this positive semi-definite
        stiffness, which makes a pulled cable resist sideways motion."""
        self._geometry_entries()
        p = np.einsum("ka,kai->ki", self._weights, x[self._nodes])
        verts = np.vstack([p, self._pulls])
        seg = verts[self._ends] - verts[self._starts]
        length = np.linalg.norm(seg, axis=1)
        safe = np.where(length > 0, length, 1.0)
        unit = seg / safe[:, None]
        lam = np.asarray(tension, dtype=float)[self._owner]
        blocks = (np.eye(3) - unit[:, :, None] * unit[:, None, :]) * np.where(
            length > 0, lam / safe, 0.0
        )[:, None, None]
        return self._g_coef[:, None, None] * blocks[self._g_segment]

    def geometric_product(
        self, x: np.ndarray, tension: np.ndarray, direction: np.ndarray
    ) -> np.ndarray:
        """-sum_s lambda_s (d^2 L_s/dx^2) d on every node (n, 3): the blocks of
        :meth:`geometric_stiffness` applied to the nodal direction `d` (n, 3), segment by
        segment ((I - u u^T)/l on the difference of its end points' motions), without forming
        the blocks: the derivative of H(x)^T lambda along d."""
        n_points = len(self._nodes)
        p = np.einsum("ka,kai->ki", self._weights, x[self._nodes])
        moved = np.einsum("ka,kai->ki", self._weights, direction[self._nodes])
        verts = np.vstack([p, self._pulls])
        moves = np.vstack([moved, np.zeros_like(self._pulls)])
        seg = verts[self._ends] - verts[self._starts]
        rel = moves[self._ends] - moves[self._starts]
        length = np.linalg.norm(seg, axis=1)
        safe = np.where(length > 0, length, 1.0)
        unit = seg / safe[:, None]
        scale = np.where(length > 0, np.asarray(tension, dtype=float)[self._owner] / safe, 0.0)
        push = (rel - unit * np.einsum("si,si->s", unit, rel)[:, None]) * scale[:, None]
        at_points = np.zeros((len(verts), 3))
        for i in range(3):
            at_points[:, i] = np.bincount(self._ends, push[:, i], len(verts)) - np.bincount(
                self._starts, push[:, i], len(verts)
            )
        spread = self._weights[:, :, None] * at_points[:n_points, None, :]
        out = np.zeros_like(x)
        nodes = self._nodes.ravel()
        for i in range(3):
            out[:, i] = -np.bincount(nodes, spread[:, :, i].ravel(), x.shape[0])
        return out

    def _geometry_entries(self) -> None:
        if hasattr(self, "_g_segment"):
            return
        n_points = len(self._nodes)
        seg, coef, ni, nj = [], [], [], []
        for s, (a, b) in enumerate(zip(self._starts, self._ends, strict=True)):
            for va, vb, sign in ((a, a, 1.0), (b, b, 1.0), (a, b, -1.0), (b, a, -1.0)):
                if va >= n_points or vb >= n_points:
                    continue
                w = sign * np.outer(self._weights[va], self._weights[vb])
                nodes_i = np.repeat(self._nodes[va], self._nodes.shape[1])
                nodes_j = np.tile(self._nodes[vb], self._nodes.shape[1])
                keep = w.reshape(-1) != 0.0
                seg.append(np.full(int(keep.sum()), s))
                coef.append(w.reshape(-1)[keep])
                ni.append(nodes_i[keep])
                nj.append(nodes_j[keep])
        empty = np.zeros(0, dtype=np.int64)
        self._g_segment = np.concatenate(seg) if seg else empty
        self._g_coef = np.concatenate(coef) if coef else np.zeros(0)
        self._g_node_i = np.concatenate(ni) if ni else empty
        self._g_node_j = np.concatenate(nj) if nj else empty


@njit(cache=True)
def _bundle_points(x, nodes, weights, pulls, starts, ends, owner, rest):
    """Shortenings L0 - L(x) of the cables and d delta / d p per embedded point (P, 3).
    Vertices are the embedded points, then the pull points."""
    n_points = nodes.shape[0]
    verts = np.empty((n_points + pulls.shape[0], 3))
    for j in range(n_points):
        for i in range(3):
            acc = 0.0
            for a in range(nodes.shape[1]):
                acc += weights[j, a] * x[nodes[j, a], i]
            verts[j, i] = acc
    verts[n_points:] = pulls
    delta = rest.copy()
    dl = np.zeros((verts.shape[0], 3))
    for s in range(starts.shape[0]):
        d = verts[ends[s]] - verts[starts[s]]
        length = np.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
        delta[owner[s]] -= length
        if length > 0.0:
            for i in range(3):
                dl[ends[s], i] += d[i] / length
                dl[starts[s], i] -= d[i] / length
    return delta, -dl[:n_points]


@njit(cache=True)
def _bundle_rows(x, nodes, weights, pulls, starts, ends, owner, rest):
    """Shortenings L0 - L(x) of the cables and their rows of H per embedded point and node
    (P, 4, 3): d delta / d p spread on each point's nodes by its weights."""
    delta, dp = _bundle_points(x, nodes, weights, pulls, starts, ends, owner, rest)
    grad = np.empty((nodes.shape[0], nodes.shape[1], 3))
    for j in range(nodes.shape[0]):
        for a in range(nodes.shape[1]):
            for i in range(3):
                grad[j, a, i] = dp[j, i] * weights[j, a]
    return delta, grad
