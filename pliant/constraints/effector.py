"""Position effector (SoftRobots' PositionEffector)."""

from __future__ import annotations

import numpy as np

from pliant.constraints.base import Constraint, EmbeddedPoints, JacobianRows, PointRowForm
from pliant.errors import ConstraintError


def _axes_and_weight(name: str, axes, weight: float) -> tuple[np.ndarray, float]:
    """The selected axes' indices and the rows' weight, checked."""
    picked = np.flatnonzero(np.asarray(axes, dtype=bool))
    if picked.size == 0 or len(axes) != 3:
        raise ConstraintError(f"{name}: axes must select at least one of x, y, z")
    if not (np.isfinite(weight) and weight > 0):
        raise ConstraintError(f"{name}: weight must be finite and > 0, got {weight!r}")
    return picked, float(weight)


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
        self.axes, self.weight = _axes_and_weight(name, axes, weight)
        self.goals = points.positions(rest_positions) if goals is None else goals

    @property
    def goals(self) -> np.ndarray:
        return self._goals

    @goals.setter
    def goals(self, goals: np.ndarray) -> None:
        self._goals = _goal_array(goals, len(self.points), self.name)

    @property
    def n_rows(self) -> int:
        return len(self.points) * self.axes.size

    def position(self, x: np.ndarray) -> np.ndarray:
        return self.points.positions(x)

    def distance(self, x: np.ndarray) -> np.ndarray:
        return self.weight * (self.points.positions(x) - self._goals)[:, self.axes].reshape(-1)

    def point_row_form(self) -> PointRowForm:
        """Constant rows: the weight on each selected axis of each point."""
        k, na = len(self.points), self.axes.size
        coefficients = np.zeros((k * na, 3 * k))
        for j in range(k):
            for i, ax in enumerate(self.axes):
                coefficients[j * na + i, 3 * j + ax] = self.weight
        return PointRowForm(self.points, coefficients)

    def jacobian(self, x: np.ndarray) -> JacobianRows:
        k, na = len(self.points), self.axes.size
        per = self.points.nodes.shape[1]
        values = np.zeros((k, na, per, 3))
        for j, ax in enumerate(self.axes):
            values[:, j, :, ax] = self.weight * self.points.weights
        nodes = np.repeat(self.points.nodes[:, None, :], na, axis=1)
        return JacobianRows(nodes.reshape(k * na, per), values.reshape(k * na, per, 3))


class RigidEffector(Constraint):
    """The centre of a rigid body of the model that should reach a goal: an object that the
    robot moves by contact (QPCC, Eq. 2.15 with complementarity).

    delta_e = weight (c - c_goal) on the selected axes, c the body's centre of mass. The rows
    have no Jacobian on the deformable body: over a step, c moves by h v, with v the body's
    velocity u = u_free + h M^-1 G^T lambda_c, so that the dynamic step
    (:class:`pliant.solvers.ImplicitEuler`) adds h J u_free to delta_free and the coupling
    h^2 J M^-1 G^T with the contact rows (and h^2 J M^-1 J^T to the effector block): the
    inverse problem sees the object move when, and only when, the robot's contacts push it.

    Args:
        body: one of the model's rigid bodies (:class:`pliant.fem.rigid.RigidBody`).
        goal: (3,) goal of its centre (default: its initial position).
        axes, weight: as :class:`PositionEffector`.
    """

    role = "effector"

    def __init__(
        self,
        body,
        *,
        goal: np.ndarray | None = None,
        axes: tuple[bool, bool, bool] = (True, True, True),
        weight: float = 1.0,
        name: str = "object",
    ) -> None:
        self.name = name
        self.body = body
        self.axes, self.weight = _axes_and_weight(name, axes, weight)
        self.centre = np.asarray(body.position, dtype=float).copy()
        self.goals = self.centre if goal is None else goal

    @property
    def goals(self) -> np.ndarray:
        return self._goals

    @goals.setter
    def goals(self, goals: np.ndarray) -> None:
        self._goals = _goal_array(goals, 1, self.name)

    @property
    def rigid_body(self):
        """The body whose centre the rows read."""
        return self.body

    @property
    def n_rows(self) -> int:
        return int(self.axes.size)

    def distance(self, x: np.ndarray) -> np.ndarray:
        """At the body's centre last set by the solver (`centre`, the step's start)."""
        return self.weight * (self.centre - self._goals[0])[self.axes]

    def jacobian(self, x: np.ndarray) -> JacobianRows:
        return JacobianRows(
            np.zeros((self.n_rows, 1), dtype=np.int64), np.zeros((self.n_rows, 1, 3))
        )

    def twist_rows(self, index: int, n_bodies: int) -> np.ndarray:
        """(rows, 6 n_bodies): d delta_e / d(h u), the rows' dependence on the twists."""
        rows = np.zeros((self.n_rows, 6 * n_bodies))
        rows[np.arange(self.n_rows), 6 * index + self.axes] = self.weight
        return rows


def _goal_array(goals, k: int, name: str) -> np.ndarray:
    """`goals` as a (k, 3) float array of finite values ((3,) or (3k,) accepted), else
    ConstraintError: text, complex numbers and shapes of another point count are refused."""
    try:
        g = np.asarray(goals)
    except (ValueError, TypeError) as exc:  # ragged nested sequences
        raise ConstraintError(f"{name}: goals must be an array of numbers: {exc}") from None
    if g.dtype.kind not in "iuf" or g.size != 3 * k or (g.ndim == 2 and g.shape != (k, 3)):
        raise ConstraintError(
            f"{name}: goals must be {k} point(s) of 3 real numbers, shape ({k}, 3); got"
            f" {type(goals).__name__} of dtype {g.dtype} and shape {g.shape}"
        )
    g = g.astype(float).reshape(k, 3)
    if not np.all(np.isfinite(g)):
        raise ConstraintError(f"{name}: goals must be finite")
    return g
