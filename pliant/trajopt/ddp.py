"""Box-constrained DDP (Tassa, Mansard and Todorov 2014) on condensed dynamics (thesis §5.2.2).

Each iteration (thesis Fig. 5.18):

1. the backward pass runs the Riccati recursion on the dynamics linearised along the nominal
   trajectory (Fx, Fu of :mod:`pliant.trajopt.dynamics`, or any system's), solving at each
   node the box QP  min_du 1/2 du^T Q_uu du + Q_u^T du  on  lo - u <= du <= hi - u  exactly
   (:func:`pliant.constraints.direct.box_qp`); the feedback gains act on the free controls
   only, K_f = -Q_uu,ff^-1 Q_ux,f, K_clamped = 0 (box-DDP);
2. the forward pass rolls the system out (for the FEM: the full model, from the initial
   state) with u_k = clip(u_k + alpha k_k + K_k (X_k - X_nominal,k)) for alpha = 1, 1/2, ...
   until the cost decreases by a fraction of the decrease the quadratic model predicts
   (Armijo); a failed search raises the regularisation of Q_uu and tries again.

Stops when the predicted decrease, or the decrease obtained, falls below `tolerance` times
the cost. Every control returned meets its bounds: the forward pass clips each control to its
node's box, whose change bound is measured from the control actually applied before it.

The backward pass may also be crocoddyl's (Box-FDDP's, on a chain of its LQR action models),
`backend="crocoddyl"`; the forward pass and the rest are the same.
"""

from __future__ import annotations

import copy
import time
from dataclasses import dataclass, field
from typing import Literal, Protocol

import numpy as np

from pliant.constraints.direct import box_qp
from pliant.errors import DivergenceError, TrajectoryOptimisationError
from pliant.trajopt.problem import ActuationBounds, QuadraticCost


class System(Protocol):
    """What the DDP needs: rollouts and their derivatives."""

    def rollout(self, start, us: np.ndarray, *, policy=None): ...

    def derivatives(self, rollout) -> tuple[np.ndarray, np.ndarray]: ...


@dataclass
class Gains:
    """The backward pass' result: feedforward k, feedback K and the predicted decrease
    terms d1 = sum k^T Q_u, d2 = sum k^T Q_uu k (decrease at alpha: -(alpha d1 + alpha^2
    d2 / 2)), and the stationarity of the nominal controls: the largest entry of Q_u
    projected on the box (zero at a KKT point of the condensed problem)."""

    k: np.ndarray
    feedback: np.ndarray
    d1: float
    d2: float
    stationarity: float

    def predicted(self, alpha: float) -> float:
        return -(alpha * self.d1 + 0.5 * alpha * alpha * self.d2)


@dataclass
class DDPResult:
    """The optimised trajectory and a convergence report."""

    us: np.ndarray
    xs: np.ndarray
    rollout: object
    cost: float
    iterations: int
    converged: bool
    reason: str
    bound_violation: float
    stationarity: float
    wall_time: float
    rollouts: int
    forward_time: float
    backward_time: float
    history: list[dict] = field(default_factory=list)

    def report(self) -> dict:
        return {
            "cost": self.cost,
            "iterations": self.iterations,
            "converged": self.converged,
            "reason": self.reason,
            "bound_violation": self.bound_violation,
            "stationarity": self.stationarity,
            "wall_time_s": self.wall_time,
            "rollouts": self.rollouts,
            "forward_time_s": self.forward_time,
            "backward_time_s": self.backward_time,
            "cost_history": [h["cost"] for h in self.history],
        }


Backend = Literal["numpy", "crocoddyl"]


class BoxDDP:
    """Box-DDP with a backtracking line search.

    Args:
        max_iterations: backward passes at most.
        tolerance: stop when the decrease predicted for a full step, or the decrease of an
            accepted step, is below tolerance * max(cost, 1e-12).
        backend: "numpy" (this module's backward pass) or "crocoddyl" (Box-FDDP's).
        alphas: the step lengths tried by the line search, in order.
        armijo: fraction of the predicted decrease an accepted step must obtain.
        min_regularisation, max_regularisation: the Levenberg term of Q_uu (relative to its
            mean diagonal) set by a first failed line search, and beyond which a failed line
            search ends the solve (multiplied by 10 at each failure, divided by 10 after
            each accepted step).
        feedback: apply the feedback gains K in the forward pass (False: open-loop steps
            u + alpha k; measured slower on the Diamond).
        change_bound: how a bound on the change per step is met: "sequential" (each node's
            box around the nominal control before it, the forward pass clipping to the control
            applied before) or "augmented" (the previous control in the state, its change the
            control: :mod:`pliant.trajopt.rate`; needs `bounds.previous`). Measured on the
            Diamond's two goals: sequential 46 iterations, 67 rollouts, cost 1171.5;
            augmented 69 iterations, 317 rollouts, cost 1154.7.
    """

    def __init__(
        self,
        *,
        max_iterations: int = 100,
        tolerance: float = 1e-6,
        backend: Backend = "numpy",
        alphas: tuple[float, ...] = (1.0, 0.5, 0.25, 0.125, 0.0625, 0.03125),
        armijo: float = 1e-4,
        min_regularisation: float = 1e-3,
        max_regularisation: float = 1e6,
        feedback: bool = True,
        change_bound: Literal["augmented", "sequential"] = "sequential",
    ) -> None:
        if change_bound not in ("augmented", "sequential"):
            raise TrajectoryOptimisationError(
                f"change_bound must be 'augmented' or 'sequential', got {change_bound!r}"
            )
        self.change_bound = change_bound
        if max_iterations < 1:
            raise TrajectoryOptimisationError(f"max_iterations must be >= 1, got {max_iterations}")
        if not (np.isfinite(tolerance) and tolerance > 0):
            raise TrajectoryOptimisationError(f"tolerance must be > 0, got {tolerance!r}")
        if backend not in ("numpy", "crocoddyl"):
            raise TrajectoryOptimisationError(
                f"backend must be 'numpy' or 'crocoddyl', got {backend!r}"
            )
        self.max_iterations = int(max_iterations)
        self.tolerance = float(tolerance)
        self.backend = backend
        self.alphas = tuple(alphas)
        self.armijo = float(armijo)
        self.min_regularisation = float(min_regularisation)
        self.max_regularisation = float(max_regularisation)
        self.feedback = bool(feedback)

    def solve(
        self,
        system: System,
        start,
        cost: QuadraticCost,
        bounds: ActuationBounds,
        us: np.ndarray | None = None,
        *,
        callback=None,
    ) -> DDPResult:
        """Optimise the controls from `start` (a FEM State, or whatever `system` rolls out
        from); `us` (N, n_u) is the initial guess (default: the bounds' projection of
        u_ref), projected onto the bounds. `callback(iteration, result_so_far_dict)` is called
        after each iteration."""
        clock = time.perf_counter()
        n = cost.horizon
        n_u = cost.control_weights.size
        if bounds.lower.size != n_u:
            raise TrajectoryOptimisationError(
                f"{bounds.lower.size} bounded controls for {n_u} weighted controls"
            )
        if us is None:
            us = np.tile(cost.control_reference, (n, 1))
        us = np.asarray(us, dtype=float)
        if us.shape != (n, n_u):
            raise TrajectoryOptimisationError(
                f"the initial controls must have shape ({n}, {n_u}), got {us.shape}"
            )
        us = bounds.project(us)
        if (
            self.change_bound == "augmented"
            and bounds.max_change is not None
            and bounds.previous is not None
        ):
            return self._solve_augmented(system, start, cost, bounds, us, callback, clock)
        forward_time = backward_time = 0.0
        t = time.perf_counter()
        try:
            nominal = system.rollout(start, us)
        except DivergenceError as exc:
            raise TrajectoryOptimisationError(
                f"the initial guess' rollout diverged: {exc}; start from smaller forces or a"
                " smaller time step"
            ) from exc
        forward_time += time.perf_counter() - t
        rollouts = 1
        if nominal.xs.shape[1] != cost.state_reference.shape[1]:
            raise TrajectoryOptimisationError(
                f"the cost's state has {cost.state_reference.shape[1]} entries, the system's"
                f" {nominal.xs.shape[1]}"
            )
        value = cost.value(nominal.xs, nominal.us)
        history = [{"cost": value, "alpha": 0.0, "predicted": 0.0, "regularisation": 0.0}]
        mu, converged, reason, gains = 0.0, False, "max_iterations", None
        iterations = 0
        while iterations < self.max_iterations:
            iterations += 1
            t = time.perf_counter()
            fx, fu = system.derivatives(nominal)
            gains = self._backward(nominal.xs, nominal.us, fx, fu, cost, bounds, mu)
            backward_time += time.perf_counter() - t
            scale = self.tolerance * max(abs(value), 1e-12)
            if gains.predicted(1.0) <= scale:
                converged, reason = True, "predicted decrease below tolerance"
                break
            accepted = None
            for alpha in self.alphas:
                t = time.perf_counter()
                try:
                    trial = system.rollout(
                        start,
                        nominal.us,
                        policy=self._policy(nominal, gains, alpha, bounds, self.feedback),
                    )
                except DivergenceError:
                    trial = None
                forward_time += time.perf_counter() - t
                rollouts += 1
                if trial is None:
                    continue
                new_value = cost.value(trial.xs, trial.us)
                if value - new_value >= self.armijo * gains.predicted(alpha) and new_value < value:
                    accepted = (alpha, trial, new_value)
                    break
            if accepted is None:
                mu = max(self.min_regularisation, 10.0 * mu)
                history.append(
                    {
                        "cost": value,
                        "alpha": 0.0,
                        "predicted": gains.predicted(1.0),
                        "regularisation": mu,
                    }
                )
                if mu > self.max_regularisation:
                    reason = "line search failed at the largest regularisation"
                    break
                continue
            alpha, nominal, new_value = accepted
            decrease = value - new_value
            value = new_value
            history.append(
                {
                    "cost": value,
                    "alpha": alpha,
                    "predicted": gains.predicted(alpha),
                    "regularisation": mu,
                }
            )
            mu = 0.0 if mu <= self.min_regularisation else mu / 10.0
            if callback is not None:
                callback(iterations, history[-1])
            if decrease <= scale:
                converged, reason = True, "cost decrease below tolerance"
                break
        return DDPResult(
            us=nominal.us,
            xs=nominal.xs,
            rollout=nominal,
            cost=value,
            iterations=iterations,
            converged=converged,
            reason=reason,
            bound_violation=bounds.violation(nominal.us),
            stationarity=gains.stationarity if gains is not None else float("nan"),
            wall_time=time.perf_counter() - clock,
            rollouts=rollouts,
            forward_time=forward_time,
            backward_time=backward_time,
            history=history,
        )

    def _solve_augmented(self, system, start, cost, bounds, us, callback, clock) -> DDPResult:
        """The solve on the rate-augmented problem (:mod:`pliant.trajopt.rate`), its result
        read back in the system's own state and controls."""
        from pliant.trajopt import rate

        n_u = us.shape[1]
        inner = copy.copy(self)  # the same settings, on a problem whose bound is a box
        inner.change_bound = "sequential"
        deltas = np.diff(np.vstack([bounds.previous, us]), axis=0)
        result = inner.solve(
            rate.RateSystem(system, bounds.previous, n_u),
            start,
            rate.rate_cost(cost, 1e-3 * cost.control_weights),
            rate.RateBounds(bounds),
            deltas,
            callback=callback,
        )
        rollout = result.rollout.inner
        result.us, result.xs, result.rollout = rollout.us, rollout.xs, rollout
        result.cost = cost.value(rollout.xs, rollout.us)
        result.bound_violation = bounds.violation(rollout.us)
        result.wall_time = time.perf_counter() - clock
        return result

    @staticmethod
    def _policy(nominal, gains: Gains, alpha: float, bounds: ActuationBounds, feedback: bool):
        applied: list[np.ndarray] = []

        def policy(k: int, x: np.ndarray, u: np.ndarray) -> np.ndarray:
            lo, hi = bounds.node_box(x, applied[-1] if applied else None)
            du = alpha * gains.k[k]
            if feedback:
                du = du + gains.feedback[k] @ (x - nominal.xs[k])
            new = np.clip(u + du, lo, hi)
            applied.append(new)
            return new

        return policy

    def _backward(self, xs, us, fx, fu, cost: QuadraticCost, bounds, mu: float) -> Gains:
        boxes = [bounds.node_box(xs[k], us[k - 1] if k > 0 else None) for k in range(len(us))]
        if self.backend == "crocoddyl":
            from pliant.trajopt import crocoddyl_backend

            return crocoddyl_backend.backward_pass(xs, us, fx, fu, cost, boxes, mu)
        return compiled_backward_pass(xs, us, fx, fu, cost, boxes, mu)


def compiled_backward_pass(xs, us, fx, fu, cost: QuadraticCost, boxes, mu: float = 0.0) -> Gains:
    """:func:`backward_pass` compiled (:mod:`pliant.trajopt.kernels`)."""
    from pliant.trajopt import kernels

    lower = np.array([b[0] for b in boxes], dtype=float)
    upper = np.array([b[1] for b in boxes], dtype=float)
    k, feedback, d1, d2, worst = kernels.backward_pass(
        np.ascontiguousarray(xs, dtype=float),
        np.ascontiguousarray(us, dtype=float),
        np.ascontiguousarray(fx, dtype=float),
        np.ascontiguousarray(fu, dtype=float),
        cost.state_weights,
        cost.state_reference,
        cost.control_weights,
        cost.control_reference,
        lower,
        upper,
        float(mu),
    )
    return Gains(k, feedback, float(d1), float(d2), float(worst))


def backward_pass(xs, us, fx, fu, cost: QuadraticCost, boxes, mu: float = 0.0) -> Gains:
    """The box-DDP backward pass along a nominal trajectory (the NumPy reference)."""
    n, n_u = us.shape
    n_x = xs.shape[1]
    q, x_ref = cost.state_weights, cost.state_reference
    r, u_ref = cost.control_weights, cost.control_reference
    lx = q * (xs - x_ref)
    lu = r * (us - u_ref)
    diag_x, diag_u = np.diag_indices(n_x), np.diag_indices(n_u)
    k_ff = np.zeros((n, n_u))
    k_fb = np.zeros((n, n_u, n_x))
    vx = lx[n].copy()
    vxx = np.diag(q[n])
    d1 = d2 = 0.0
    worst = 0.0
    for t in range(n - 1, -1, -1):
        a, b = fx[t], fu[t]
        vxx_b = vxx @ b
        qx = lx[t] + a.T @ vx
        qu = lu[t] + b.T @ vx
        qxx = a.T @ vxx @ a
        qxx[diag_x] += q[t]
        quu = b.T @ vxx_b
        quu[diag_u] += r
        qux = vxx_b.T @ a
        quu_reg = quu
        if mu:
            quu_reg = quu.copy()
            quu_reg[diag_u] += mu * np.mean(quu[diag_u])
        lo, hi = boxes[t][0] - us[t], boxes[t][1] - us[t]
        # The unconstrained Newton step and gains in one solve; the box QP only when the
        # step leaves the box.
        sol = np.linalg.solve(quu_reg, np.column_stack([qu, qux]))
        du, gain = -sol[:, 0], -sol[:, 1:]
        if np.any(du < lo) or np.any(du > hi):
            du = box_qp(quu_reg, qu, lo, hi)
            free = (du > lo) & (du < hi)
            gain = np.zeros((n_u, n_x))
            if free.any():
                gain[free] = -np.linalg.solve(quu_reg[np.ix_(free, free)], qux[free])
        # First-order stationarity at the nominal controls: the gradient projected on the box.
        projected = np.where(lo >= 0.0, np.minimum(qu, 0.0), qu)
        projected = np.where(hi <= 0.0, np.maximum(projected, 0.0), projected)
        worst = max(worst, float(np.abs(projected).max()))
        k_ff[t], k_fb[t] = du, gain
        quu_du = quu @ du
        d1 += float(du @ qu)
        d2 += float(du @ quu_du)
        gain_quu = gain.T @ quu
        vx = qx + gain_quu @ du + gain.T @ qu + qux.T @ du
        vxx = qxx + gain_quu @ gain + gain.T @ qux + qux.T @ gain
        vxx = 0.5 * (vxx + vxx.T)
    return Gains(k_ff, k_fb, d1, d2, worst)
