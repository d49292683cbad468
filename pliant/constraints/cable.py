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

    def polyline(self, x: np.ndarray) -> np.ndarray:
        """Current cable path, for drawing."""
        return self._polyline(x)
