"""Linear time-varying dynamics X_{k+1} = A_k X_k + B_k u_k + c_k with the DDP's interface.

Serves the verification (a mass-spring system whose optimum is the LQR's) and the condensed
problem frozen along a FEM rollout (its Fx, Fu, and the drift c_k that makes the nominal
trajectory exact), on which the numpy and crocoddyl solvers are compared.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pliant.errors import DivergenceError, TrajectoryOptimisationError


@dataclass
class LinearRollout:
    xs: np.ndarray
    us: np.ndarray


class LinearDynamics:
    """X_{k+1} = A_k X_k + B_k u_k + c_k over N nodes (A, B, c: one per node, or shared)."""

    def __init__(self, a: np.ndarray, b: np.ndarray, c: np.ndarray | None = None) -> None:
        a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
        if a.ndim == 2:
            a = a[None]
        if b.ndim == 2:
            b = b[None]
        c = None if c is None else np.asarray(c, dtype=float).reshape(-1, a.shape[1])
        n = max(a.shape[0], b.shape[0], 1 if c is None else c.shape[0])
        self.a = np.broadcast_to(a, (n, *a.shape[1:]))
        self.b = np.broadcast_to(b, (n, *b.shape[1:]))
        n_x = self.a.shape[1]
        if self.a.shape[1:] != (n_x, n_x) or self.b.shape[1] != n_x:
            raise TrajectoryOptimisationError(
                f"A must be (n_x, n_x) and B (n_x, n_u), got {a.shape[1:]} and {b.shape[1:]}"
            )
        self.c = np.zeros((n, n_x)) if c is None else np.broadcast_to(c, (n, n_x))

    @classmethod
    def along(cls, xs: np.ndarray, us: np.ndarray, fx: np.ndarray, fu: np.ndarray):
        """The dynamics linearised along a trajectory, the drift set so that it is exact
        there: c_k = X_{k+1} - Fx_k X_k - Fu_k u_k."""
        c = xs[1:] - np.einsum("kij,kj->ki", fx, xs[:-1]) - np.einsum("kij,kj->ki", fu, us)
        return cls(fx, fu, c)

    def rollout(self, start: np.ndarray, us: np.ndarray, *, policy=None) -> LinearRollout:
        us = np.array(us, dtype=float)
        n = us.shape[0]
        xs = np.zeros((n + 1, self.a.shape[1]))
        xs[0] = start
        for k in range(n):
            if policy is not None:
                us[k] = policy(k, xs[k], us[k])
            j = k if self.a.shape[0] > 1 else 0
            with np.errstate(over="ignore", invalid="ignore"):  # divergence is reported below
                xs[k + 1] = self.a[j] @ xs[k] + self.b[j] @ us[k] + self.c[j]
            if not np.all(np.isfinite(xs[k + 1])):
                raise DivergenceError(
                    f"the linear rollout diverged at node {k}", step=k, cause="rollout"
                )
        return LinearRollout(xs, us)

    def derivatives(self, rollout: LinearRollout) -> tuple[np.ndarray, np.ndarray]:
        n = rollout.us.shape[0]
        return (
            np.broadcast_to(self.a, (n, *self.a.shape[1:])).copy(),
            np.broadcast_to(self.b, (n, *self.b.shape[1:])).copy(),
        )
