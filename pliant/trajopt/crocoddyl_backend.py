"""crocoddyl (Mastalli et al. 2020) on the condensed problem: a chain of its LQR action models.

Node k of the condensed problem, frozen along a nominal trajectory, is crocoddyl's
``ActionModelLQR(A_k, B_k, Q_k, R, 0, c_k, -Q_k X_ref,k, -R u_ref)`` (dynamics
X' = A X + B u + c, cost 1/2 X^T Q X + 1/2 u^T R u + q^T X + r^T u, the same as
:class:`pliant.trajopt.problem.QuadraticCost` up to a constant) with its control box. Used two
ways: Box-FDDP's backward pass inside :class:`pliant.trajopt.ddp.BoxDDP` (the FEM forward pass
stays Pliant's), and Box-FDDP's whole solve on the frozen problem (:func:`solve_frozen`).
crocoddyl's gains move the controls by -k - K dx; Pliant's by +k + K dx.
"""

from __future__ import annotations

import time

import numpy as np

from pliant.errors import TrajectoryOptimisationError
from pliant.trajopt.problem import ActuationBounds, QuadraticCost


def _crocoddyl():
    try:
        import crocoddyl
    except ImportError as exc:  # pragma: no cover - crocoddyl is a test dependency
        raise TrajectoryOptimisationError(
            "the crocoddyl backend needs crocoddyl (pip install crocoddyl)"
        ) from exc
    return crocoddyl


def shooting_problem(x0, fx, fu, drift, cost: QuadraticCost, boxes):
    """crocoddyl's ShootingProblem of the frozen condensed problem."""
    croc = _crocoddyl()
    n, n_x, n_u = fu.shape
    r = np.diag(cost.control_weights)
    r_lin = -cost.control_weights * cost.control_reference
    cross = np.zeros((n_x, n_u))
    models = []
    for k in range(n + 1):
        j = min(k, n - 1)
        q = cost.state_weights[k]
        model = croc.ActionModelLQR(
            fx[j], fu[j], np.diag(q), r, cross, drift[j], -q * cost.state_reference[k], r_lin
        )
        if k < n:
            model.u_lb, model.u_ub = boxes[k]
        models.append(model)
    return croc.ShootingProblem(np.asarray(x0, dtype=float), models[:-1], models[-1])


def backward_pass(xs, us, fx, fu, cost: QuadraticCost, boxes, mu: float = 0.0):
    """Box-FDDP's backward pass along (xs, us), as :class:`pliant.trajopt.ddp.Gains`."""
    from pliant.trajopt.ddp import Gains

    croc = _crocoddyl()
    drift = xs[1:] - np.einsum("kij,kj->ki", fx, xs[:-1]) - np.einsum("kij,kj->ki", fu, us)
    problem = shooting_problem(xs[0], fx, fu, drift, cost, [_finite(b) for b in boxes])
    solver = croc.SolverBoxFDDP(problem)
    solver.setCandidate(list(xs), list(us), True)
    solver.preg = solver.dreg = float(mu) * _mean_diag(cost) if mu else 0.0
    solver.computeDirection(True)
    k = -np.array(solver.k)
    feedback = -np.array(solver.K)
    # Q_u and Q_uu from the value function (the bindings' own Qu reads back zeros).
    vx, vxx = np.array(solver.Vx[1:]), np.array(solver.Vxx[1:])
    qu = cost.control_weights * (us - cost.control_reference) + np.einsum("kxu,kx->ku", fu, vx)
    quu = np.einsum("kxu,kxy,kyv->kuv", fu, vxx, fu) + np.diag(cost.control_weights)
    d1 = float(np.einsum("ki,ki->", k, qu))
    d2 = float(np.einsum("ki,kij,kj->", k, quu, k))
    lo = np.array([b[0] for b in boxes])
    hi = np.array([b[1] for b in boxes])
    projected = np.where(us <= lo, np.minimum(qu, 0.0), qu)
    projected = np.where(us >= hi, np.maximum(projected, 0.0), projected)
    return Gains(k, feedback, d1, d2, float(np.max(np.abs(projected))))


def _mean_diag(cost: QuadraticCost) -> float:
    return float(np.mean(cost.control_weights))


def _finite(box):
    """crocoddyl's box QP wants finite bounds: infinite ones become very wide finite ones."""
    lo, hi = box
    return np.maximum(lo, -1e300), np.minimum(hi, 1e300)


def solve_frozen(
    x0,
    fx,
    fu,
    drift,
    cost: QuadraticCost,
    bounds: ActuationBounds,
    us: np.ndarray,
    *,
    max_iterations: int = 100,
    tolerance: float = 1e-9,
):
    """Box-FDDP's solve of the frozen (linear time-varying) problem: (xs, us, iterations,
    wall time)."""
    if bounds.max_change is not None:
        raise TrajectoryOptimisationError(
            "crocoddyl's box takes fixed bounds per node: solve_frozen has no change bound"
        )
    croc = _crocoddyl()
    problem = shooting_problem(
        x0, fx, fu, drift, cost, [_finite((bounds.lower, bounds.upper))] * fu.shape[0]
    )
    solver = croc.SolverBoxFDDP(problem)
    solver.th_stop = tolerance
    start = time.perf_counter()
    xs0 = [np.asarray(x0, dtype=float)] * (fu.shape[0] + 1)
    solver.solve(xs0, list(np.asarray(us, dtype=float)), max_iterations, False)
    wall = time.perf_counter() - start
    return np.array(solver.xs), np.array(solver.us), solver.iter, wall
