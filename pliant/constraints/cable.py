"""Cable actuator (SoftRobots' CableConstraint)."""

from __future__ import annotations

import numpy as np

from pliant.constraints.base import Actuator, EmbeddedPoints, JacobianRows
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

    def jacobian(self, x: np.ndarray) -> JacobianRows:
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
        grad = -dl[:, None, :] * self.points.weights[:, :, None]  # d delta / d node, (k, 4, 3)
        return JacobianRows(self.points.nodes.reshape(1, -1), grad.reshape(1, -1, 3))

    @classmethod
    def bundle(cls, cables: list[CableActuator]) -> CableBundle:
        return CableBundle(cables)

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
        self._point_owner = np.empty(n_points, dtype=np.int64)
        for i, c in enumerate(cables):
            k = len(c.points)
            verts = list(range(offset, offset + k))
            if c.pull_point is not None:
                verts = [pull_index, *verts]
                pull_index += 1
            starts += verts[:-1]
            ends += verts[1:]
            owner += [i] * (len(verts) - 1)
            self._point_owner[offset : offset + k] = i
            offset += k
        self._starts = np.array(starts)
        self._ends = np.array(ends)
        self._owner = np.array(owner)
        self._n_vertices = pull_index
        self._rest = np.array([c.rest_length for c in cables])
        width = max(4 * len(c.points) for c in cables)
        self._rows = np.zeros((self.n_rows, width), dtype=np.int64)
        self._cols = np.zeros((self.n_rows, width), dtype=np.int64)
        self._valid = np.zeros((self.n_rows, width), dtype=bool)
        offset = 0
        for i, c in enumerate(cables):
            k = 4 * len(c.points)
            self._rows[i, :k] = i
            self._cols[i, :k] = np.arange(4 * offset, 4 * offset + k)
            self._valid[i, :k] = True
            offset += len(c.points)

    def _segments(self, x: np.ndarray):
        p = np.einsum("ka,kai->ki", self._weights, x[self._nodes])
        verts = np.vstack([p, self._pulls])
        seg = verts[self._ends] - verts[self._starts]
        length = np.sqrt(np.einsum("ij,ij->i", seg, seg))
        return seg, length

    def distance(self, x: np.ndarray) -> np.ndarray:
        _, length = self._segments(x)
        return self._distance(length)

    def _distance(self, length: np.ndarray) -> np.ndarray:
        return self._rest - np.bincount(self._owner, weights=length, minlength=self.n_rows)

    def distance_and_jacobian(self, x: np.ndarray) -> tuple[np.ndarray, JacobianRows]:
        seg, length = self._segments(x)
        return self._distance(length), self._jacobian(seg, length)

    def jacobian(self, x: np.ndarray) -> JacobianRows:
        return self._jacobian(*self._segments(x))

    def _jacobian(self, seg: np.ndarray, length: np.ndarray) -> JacobianRows:
        unit = np.divide(seg, length[:, None], out=np.zeros_like(seg), where=length[:, None] > 0)
        dl = np.zeros((self._n_vertices, 3))
        for axis in range(3):
            dl[:, axis] = np.bincount(self._ends, weights=unit[:, axis], minlength=self._n_vertices)
            dl[:, axis] -= np.bincount(
                self._starts, weights=unit[:, axis], minlength=self._n_vertices
            )
        n_points = len(self._nodes)
        grad = -dl[:n_points, None, :] * self._weights[:, :, None]  # (P, 4, 3)
        values = np.where(self._valid[:, :, None], grad.reshape(-1, 3)[self._cols], 0.0)
        nodes = np.where(self._valid, self._nodes.reshape(-1)[self._cols], 0)
        return JacobianRows(nodes, values)
