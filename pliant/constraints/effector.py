"""Position effector (SoftRobots' PositionEffector)."""

from __future__ import annotations

import numpy as np

from pliant.constraints.base import Constraint, EmbeddedPoints, JacobianRows
from pliant.errors import ConstraintError


class PositionEffector(Constraint):
    """Points of the body that should reach goals: delta_e = p - p_goal on selected axes (Eq. 2.13).

    Args:
        points: the effector points, embedded in the body.
        goals: (k, 3) goal positions (default: the rest positions of the points).
        axes: which of x, y, z are controlled, e.g. (True, True, False).
        weight: scales the rows (relative importance in the inverse problem).
    """

    role = "effector"

    def __init__(
        self,
        points: EmbeddedPoints,
        rest_positions: np.ndarray,
        *,
        goals: np.ndarray | None = None,
        axes: tuple[bool, bool, bool] = (True, True, True),
        weight: float = 1.0,
        name: str = "effector",
    ) -> None:
        self.name = name
        self.points = points
        self.axes = np.flatnonzero(np.asarray(axes, dtype=bool))
        if self.axes.size == 0 or len(axes) != 3:
            raise ConstraintError(f"{name}: axes must select at least one of x, y, z")
        if not (np.isfinite(weight) and weight > 0):
            raise ConstraintError(f"{name}: weight must be finite and > 0, got {weight!r}")
        self.weight = float(weight)
        self.goals = points.positions(rest_positions) if goals is None else goals

    @property
    def goals(self) -> np.ndarray:
        return self._goals

    @goals.setter
    def goals(self, goals: np.ndarray) -> None:
        g = np.asarray(goals, dtype=float).reshape(-1, 3) if np.size(goals) else np.empty((0, 3))
        if g.shape != (len(self.points), 3):
            raise ConstraintError(
                f"{self.name}: goals must have shape ({len(self.points)}, 3), got {np.shape(goals)}"
            )
        if not np.all(np.isfinite(g)):
            raise ConstraintError(f"{self.name}: goals must be finite")
        self._goals = g

    @property
    def n_rows(self) -> int:
        return len(self.points) * self.axes.size

    def position(self, x: np.ndarray) -> np.ndarray:
        return self.points.positions(x)

    def distance(self, x: np.ndarray) -> np.ndarray:
        return self.weight * (self.points.positions(x) - self._goals)[:, self.axes].reshape(-1)

    def jacobian(self, x: np.ndarray) -> JacobianRows:
        k, na = len(self.points), self.axes.size
        values = np.zeros((k, na, 4, 3))
        for j, ax in enumerate(self.axes):
            values[:, j, :, ax] = self.weight * self.points.weights
        nodes = np.repeat(self.points.nodes[:, None, :], na, axis=1)
        return JacobianRows(nodes.reshape(k * na, 4), values.reshape(k * na, 4, 3))
