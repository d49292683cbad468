"""Inverse problem (Eq. 2.15): actuator forces that bring the effectors to their goals."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from proxsuite import proxqp

from pliant.constraints.base import Actuator
from pliant.constraints.condensed import CondensedProblem
from pliant.errors import InfeasibleProblemError, SolverError


@dataclass
class InverseSolution:
    actuation: np.ndarray
    predicted_effector_distance: np.ndarray
    iterations: int


def solve_inverse(
    problem: CondensedProblem,
    actuators: list[Actuator],
    previous_displacement: np.ndarray,
    *,
    regularisation: float = 1e-3,
    tolerance: float = 1e-9,
    max_iterations: int = 1000,
) -> InverseSolution:
    """min ||W_ea l + d_e_free||^2 + eps l^T W_aa l  s.t. effort and course bounds.

    The regularisation eps is relative: eps = regularisation * ||W_ea^T W_ea|| / ||W_aa||
    (Frobenius norms), so that it does not depend on the scene's units. ProxQP (proxsuite)
    solves the QP; bounds that admit no solution raise InfeasibleProblemError.
    """
    na = len(actuators)
    if na == 0:
        raise InfeasibleProblemError("inverse control needs at least one actuator")
    sa, se = problem.slices["actuator"], problem.slices["effector"]
    if se.stop == se.start:
        raise InfeasibleProblemError("inverse control needs at least one effector")
    w_ea = problem.compliance[se, sa]
    w_aa = problem.compliance[sa, sa]
    de_free = problem.free_distance[se]
    da_free = problem.free_distance[sa]
    lo = np.array([a.min_force for a in actuators])
    hi = np.array([a.max_force for a in actuators])
    dmin = np.array([a.min_displacement for a in actuators])
    dmax = np.array([a.max_displacement for a in actuators])
    for i, a in enumerate(actuators):
        if a.max_displacement_change is not None:
            dmin[i] = max(dmin[i], previous_displacement[i] - a.max_displacement_change)
            dmax[i] = min(dmax[i], previous_displacement[i] + a.max_displacement_change)
    if np.any(lo > hi) or np.any(dmin > dmax):
        raise InfeasibleProblemError("actuator bounds with lower > upper admit no solution")

    # Solve in displacement units: lambda = mu / c with c the mean actuator compliance, so that
    # the QP's data are O(1) whatever the scene's units and time step.
    c = float(np.mean(np.abs(np.diag(w_aa))))
    if not c > 0:
        raise SolverError("the actuators have zero compliance: they cannot move the robot")
    hess = w_ea.T @ w_ea
    eps = regularisation * np.linalg.norm(hess) / max(np.linalg.norm(w_aa), 1e-300)
    hess = (hess + eps * 0.5 * (w_aa + w_aa.T)) / c**2
    grad = (w_ea.T @ de_free) / c
    # proxsuite wants finite bounds: replace infinities by a bound far outside the solution.
    big = 1e20
    qp = proxqp.dense.QP(na, 0, na, True)
    qp.settings.eps_abs = tolerance
    qp.settings.eps_rel = 0.0
    qp.settings.max_iter = max_iterations
    qp.init(
        hess,
        grad,
        None,
        None,
        w_aa / c,
        np.clip(dmin - da_free, -big, big),
        np.clip(dmax - da_free, -big, big),
        np.clip(lo * c, -big, big),
        np.clip(hi * c, -big, big),
    )
    qp.solve()
    status = qp.results.info.status
    if status == proxqp.QPSolverOutput.PROXQP_PRIMAL_INFEASIBLE:
        raise InfeasibleProblemError(
            "the actuators' effort and course bounds cannot be met together at this step"
            f" (course bounds on delta_a - delta_a_free: [{dmin - da_free}, {dmax - da_free}])"
        )
    if status != proxqp.QPSolverOutput.PROXQP_SOLVED:
        raise SolverError(f"ProxQP did not solve the inverse problem: {status}")
    lam = np.clip(qp.results.x / c, lo, hi)
    return InverseSolution(lam, w_ea @ lam + de_free, int(qp.results.info.iter))
