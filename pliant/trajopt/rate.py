"""The bound on the change of actuation per step as a box, by augmenting the state.

|u_k - u_{k-1}| <= max_change couples consecutive controls, which a box-DDP cannot see at one
node. With the previous control in the state and its change as the control,

    X~_k = [X_k; u_{k-1}],   d_k = u_k - u_{k-1},
    X~_{k+1} = [f(X_k, u_{k-1} + d_k); u_{k-1} + d_k],
    Fx~ = [[Fx, Fu], [0, I]],   Fu~ = [Fu; I],

the change bound is the box -max_change <= d_k <= max_change, and the feedback on u_{k-1}
lets a ramp move as a whole within one iteration. The bounds on u itself become
u_min - u_{k-1} <= d_k <= u_max - u_{k-1}: a box at the nominal u_{k-1} in the backward pass,
at the control actually applied in the forward pass. The actuation cost R on u_k moves to the
next node's state (the same total), and d carries a small weight of its own (R~ > 0).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pliant.trajopt.problem import ActuationBounds, QuadraticCost


@dataclass
class RateRollout:
    """An augmented rollout: xs (N + 1, n_x + n_u), us the changes d (N, n_u), and the
    system's own rollout (`inner`: its controls u)."""

    xs: np.ndarray
    us: np.ndarray
    inner: object


class RateBounds:
    """The boxes of the changes d_k given u_{k-1} (the last n_u entries of the state)."""

    def __init__(self, bounds: ActuationBounds) -> None:
        self.bounds = bounds
        self.lower = -bounds.max_change
        self.upper = bounds.max_change
        self.max_change = None

    def node_box(self, x: np.ndarray, previous) -> tuple[np.ndarray, np.ndarray]:
        u_prev = x[-self.lower.size :]
        return (
            np.maximum(self.lower, self.bounds.lower - u_prev),
            np.minimum(self.upper, self.bounds.upper - u_prev),
        )

    def controls(self, deltas: np.ndarray) -> np.ndarray:
        return self.bounds.previous + np.cumsum(deltas, axis=0)

    def project(self, deltas: np.ndarray) -> np.ndarray:
        us = self.bounds.project(self.controls(deltas))
        return np.diff(np.vstack([self.bounds.previous, us]), axis=0)

    def violation(self, deltas: np.ndarray) -> float:
        return self.bounds.violation(self.controls(deltas))


class RateSystem:
    """A system seen with the previous control in its state and the change as its control."""

    def __init__(self, system, previous: np.ndarray, n_u: int) -> None:
        self.system = system
        self.previous = np.asarray(previous, dtype=float)
        self.n_u = n_u

    def rollout(self, start, deltas: np.ndarray, *, policy=None) -> RateRollout:
        applied = [self.previous]
        changes = []

        def inner_policy(k: int, x: np.ndarray, u: np.ndarray) -> np.ndarray:
            d = deltas[k]
            if policy is not None:
                d = policy(k, np.concatenate([x, applied[-1]]), d)
            changes.append(d)
            applied.append(applied[-1] + d)
            return applied[-1]

        us = self.previous + np.cumsum(deltas, axis=0)
        inner = self.system.rollout(start, us, policy=inner_policy)
        xs = np.hstack([inner.xs, np.vstack(applied)])
        return RateRollout(xs, np.array(changes), inner)

    def derivatives(self, rollout: RateRollout) -> tuple[np.ndarray, np.ndarray]:
        fx, fu = self.system.derivatives(rollout.inner)
        n, n_x, n_u = fu.shape
        big_fx = np.zeros((n, n_x + n_u, n_x + n_u))
        big_fx[:, :n_x, :n_x] = fx
        big_fx[:, :n_x, n_x:] = fu
        big_fx[:, n_x:, n_x:] = np.eye(n_u)
        big_fu = np.concatenate([fu, np.broadcast_to(np.eye(n_u), (n, n_u, n_u))], axis=1)
        return big_fx, big_fu


def rate_cost(cost: QuadraticCost, rate_weight: np.ndarray) -> QuadraticCost:
    """The augmented cost: R on u_k as a state cost at node k + 1, `rate_weight` on d."""
    n1 = cost.state_reference.shape[0]
    n_u = cost.control_weights.size
    weights_u = np.tile(cost.control_weights, (n1, 1))
    weights_u[0] = 0.0  # u_{-1} is given
    return QuadraticCost(
        np.hstack([cost.state_reference, np.tile(cost.control_reference, (n1, 1))]),
        np.hstack([cost.state_weights, weights_u]),
        np.broadcast_to(rate_weight, (n_u,)).copy(),
        np.zeros(n_u),
    )
