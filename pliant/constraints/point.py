"""A point pushed along a direction (SoftRobots' PositionConstraint, one row of it)."""

from __future__ import annotations

import numpy as np

from pliant.constraints.base import Actuator, EmbeddedPoints, JacobianRows
from pliant.errors import ConstraintError


class PointActuator(Actuator):
    """One point of the body driven along a fixed direction: delta = w d . (p(x) - p(X)), the
    point's displacement from rest along the unit direction `d`, scaled by `weight`; lambda is
    the force along `d` (the body receives lambda w d at the point).

    In displacement mode the point is moved by `value` along `d` (within the force bounds); in
    force mode it is pushed by the force `value`. SoftRobots' PositionConstraint is one such
    row for each of its points and each axis its ``useDirections`` selects.

    Args:
        point: the point, embedded in the body (one point).
        rest_positions: the body's rest positions (where the displacement is measured from).
        direction: (3,) the direction (normalised here).
        weight: scales the row (SoftRobots' ``weight``), > 0.
        Other keywords: see :class:`Actuator`; min_force defaults to -inf (it pushes and pulls).
    """

    def __init__(
        self,
        point: EmbeddedPoints,
        rest_positions: np.ndarray,
        direction,
        *,
        weight: float = 1.0,
        name: str = "point",
        min_force: float = -np.inf,
        **bounds,
    ) -> None:
        super().__init__(name=name, min_force=min_force, **bounds)
        if len(point) != 1:
            raise ConstraintError(f"{name}: one point per row, got {len(point)}")
        d = np.asarray(direction, dtype=float).reshape(-1)
        norm = float(np.linalg.norm(d)) if d.size == 3 else 0.0
        if not (np.all(np.isfinite(d)) and norm > 0):
            raise ConstraintError(f"{name}: the direction must be a finite non-zero 3-vector")
        if not (np.isfinite(weight) and weight > 0):
            raise ConstraintError(f"{name}: weight must be finite and > 0, got {weight!r}")
        self.point = point
        self.direction = d / norm
        self.weight = float(weight)
        self.rest = point.positions(rest_positions)[0]

    def distance(self, x: np.ndarray) -> np.ndarray:
        return np.array([self.weight * (self.point.positions(x)[0] - self.rest) @ self.direction])

    def jacobian(self, x: np.ndarray) -> JacobianRows:
        values = self.weight * self.point.weights[0][:, None] * self.direction[None, :]
        return JacobianRows(self.point.nodes[:1].copy(), values[None])
