"""The optimal control problem's costs and actuation bounds (thesis Eq. 2.10, 5.28).

Cost (quadratic, diagonal weights):

    J = sum_{k<N} 1/2 (X_k - X_ref,k)^T Q_k (X_k - X_ref,k) + 1/2 (u_k - u_ref)^T R (u_k - u_ref)
        + 1/2 (X_N - X_ref,N)^T Q_N (X_N - X_ref,N)

with X = [p; p_dot]: effector tracking (a goal per node, or sparse goals: nodes without one
weigh zero), effector velocity and actuation regularisation. Bounds (Eq. 5.28):
u_min <= u_k <= u_max and, when set, |u_k - u_{k-1}| <= max_change.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pliant.errors import ConstraintError, InfeasibleProblemError, TrajectoryOptimisationError


def _weights(name: str, value, shape: tuple[int, ...]) -> np.ndarray:
    try:
        w = np.broadcast_to(np.asarray(value, dtype=float), shape).copy()
    except ValueError as exc:
        raise TrajectoryOptimisationError(
            f"{name}: expected a scalar or shape {shape}, got shape {np.shape(value)}"
        ) from exc
    if not np.all(np.isfinite(w)):
        raise TrajectoryOptimisationError(f"{name} must be finite")
    if np.any(w < 0):
        raise TrajectoryOptimisationError(
            f"{name} must be >= 0 (a negative weight makes the cost unbounded below)"
        )
    return w


@dataclass(frozen=True)
class QuadraticCost:
    """Diagonal quadratic cost around a reference trajectory.

    Attributes:
        state_reference: (N + 1, n_x) X_ref,k.
        state_weights: (N + 1, n_x) diagonals of Q_k (row N: the terminal cost).
        control_weights: (n_u,) diagonal of R (> 0: the backward pass needs R positive).
        control_reference: (n_u,) u_ref.
    """

    state_reference: np.ndarray
    state_weights: np.ndarray
    control_weights: np.ndarray
    control_reference: np.ndarray

    def __post_init__(self) -> None:
        ref = np.asarray(self.state_reference, dtype=float)
        if ref.ndim != 2 or ref.shape[0] < 2:
            raise TrajectoryOptimisationError(
                f"the horizon must be >= 1 node: state_reference has shape {ref.shape}"
            )
        if not np.all(np.isfinite(ref)):
            raise TrajectoryOptimisationError("state_reference must be finite")
        object.__setattr__(self, "state_reference", ref)
        object.__setattr__(
            self, "state_weights", _weights("state_weights", self.state_weights, ref.shape)
        )
        r = _weights("control_weights", self.control_weights, np.shape(self.control_weights))
        if r.ndim != 1 or np.any(r <= 0):
            raise TrajectoryOptimisationError(
                "control_weights must be a vector of weights > 0 (R positive definite keeps"
                " the backward pass well posed)"
            )
        object.__setattr__(self, "control_weights", r)
        u_ref = np.broadcast_to(np.asarray(self.control_reference, dtype=float), r.shape).copy()
        object.__setattr__(self, "control_reference", u_ref)

    @property
    def horizon(self) -> int:
        return self.state_reference.shape[0] - 1

    def value(self, xs: np.ndarray, us: np.ndarray) -> float:
        dx = xs - self.state_reference
        du = us - self.control_reference
        return 0.5 * float(np.sum(self.state_weights * dx * dx)) + 0.5 * float(
            np.sum(self.control_weights * du * du)
        )


def tracking_cost(
    goals: np.ndarray,
    *,
    n_controls: int,
    position_weight: float | np.ndarray = 1.0,
    velocity_weight: float | np.ndarray = 0.0,
    control_weight: float | np.ndarray = 1e-6,
    terminal_weight: float = 1.0,
    control_reference: float | np.ndarray = 0.0,
) -> QuadraticCost:
    """Effector tracking: goals (N + 1, m) for the m effector rows at every node (NaN rows:
    no goal at that node), velocity and actuation weights; the terminal node's weights are
    multiplied by `terminal_weight`."""
    goals = np.asarray(goals, dtype=float)
    if goals.ndim != 2 or goals.shape[0] < 2:
        raise TrajectoryOptimisationError(
            f"the horizon must be >= 1: goals need shape (N + 1, m) with N >= 1, got {goals.shape}"
        )
    n1, m = goals.shape
    wp = _weights("position_weight", position_weight, (n1, m))
    wv = _weights("velocity_weight", velocity_weight, (n1, m))
    tw = float(_weights("terminal_weight", terminal_weight, ()))
    missing = ~np.isfinite(goals)
    wp[missing] = 0.0
    ref = np.hstack([np.where(missing, 0.0, goals), np.zeros((n1, m))])
    weights = np.hstack([wp, wv])
    weights[-1] *= tw
    r = _weights("control_weight", control_weight, (n_controls,))
    return QuadraticCost(ref, weights, r, control_reference)


@dataclass(frozen=True)
class ActuationBounds:
    """u_min <= u_k <= u_max (Eq. 5.28) and |u_k - u_{k-1}| <= max_change (None: unbounded).

    `previous` is the actuation before the first node (the change of u_0 is measured from it).
    """

    lower: np.ndarray
    upper: np.ndarray
    max_change: np.ndarray | None = None
    previous: np.ndarray | None = None

    def __post_init__(self) -> None:
        lo = np.atleast_1d(np.asarray(self.lower, dtype=float))
        hi = np.broadcast_to(np.asarray(self.upper, dtype=float), lo.shape).copy()
        if np.any(np.isnan(lo)) or np.any(np.isnan(hi)):
            raise ConstraintError("actuation bounds must not be NaN")
        if np.any(lo > hi):
            bad = np.flatnonzero(lo > hi).tolist()
            raise InfeasibleProblemError(
                f"actuation bounds with lower > upper (actuators {bad}) admit no control"
            )
        object.__setattr__(self, "lower", lo)
        object.__setattr__(self, "upper", hi)
        if self.max_change is not None:
            dc = np.broadcast_to(np.asarray(self.max_change, dtype=float), lo.shape).copy()
            if not np.all(dc > 0):  # NaN fails too
                raise InfeasibleProblemError(
                    "max_change must be > 0: a zero change per step freezes the actuation"
                )
            object.__setattr__(self, "max_change", dc)
        if self.previous is not None:
            prev = np.broadcast_to(np.asarray(self.previous, dtype=float), lo.shape).copy()
            if self.max_change is not None and np.any((prev < lo) | (prev > hi)):
                raise InfeasibleProblemError(
                    f"the actuation before the first node {prev.tolist()} is outside the"
                    " bounds: with a bounded change per step the first nodes are infeasible"
                )
            object.__setattr__(self, "previous", prev)

    def box(self, previous: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
        """The bounds of one node given the control of the node before (None: first node)."""
        if previous is None:
            previous = self.previous
        if self.max_change is None or previous is None:
            return self.lower, self.upper
        return (
            np.maximum(self.lower, previous - self.max_change),
            np.minimum(self.upper, previous + self.max_change),
        )

    def node_box(self, x: np.ndarray, previous) -> tuple[np.ndarray, np.ndarray]:
        """The box of a node reached at state x (unused here) after the control `previous`."""
        return self.box(previous)

    def project(self, us: np.ndarray) -> np.ndarray:
        """The closest controls, node by node, that meet every bound (an initial guess)."""
        out = np.array(us, dtype=float)
        prev = None
        for k in range(out.shape[0]):
            lo, hi = self.box(prev)
            out[k] = np.clip(out[k], lo, hi)
            prev = out[k]
        return out

    def violation(self, us: np.ndarray) -> float:
        """The largest amount by which `us` leaves its bounds (0 when feasible)."""
        worst, prev = 0.0, None
        for u in np.asarray(us, dtype=float):
            lo, hi = self.box(prev)
            worst = max(worst, float(np.max(lo - u, initial=0.0)))
            worst = max(worst, float(np.max(u - hi, initial=0.0)))
            prev = u
        return worst
