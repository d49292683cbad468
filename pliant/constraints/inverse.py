"""Inverse problem (Eq. 2.15): actuator forces that bring the effectors to their goals."""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
from proxsuite import proxqp
from scipy.optimize import linprog

from pliant.constraints.base import Actuator, actuator_bounds
from pliant.constraints.condensed import CondensedProblem
from pliant.errors import InfeasibleProblemError, SolverError


class InfeasibleCourseWarning(UserWarning):
    """The actuators' course bounds were widened to keep the inverse problem feasible."""


@dataclass
class InverseSolution:
    actuation: np.ndarray
    predicted_effector_distance: np.ndarray
    iterations: int


def _course_relaxation(c_mat, lower, upper, lo_box, hi_box) -> np.ndarray:
    """Smallest s >= 0 (sum) with lower - s <= C x <= upper + s and lo <= x <= hi (an LP)."""
    n, m = c_mat.shape[1], c_mat.shape[0]
    cost = np.concatenate([np.zeros(n), np.ones(m)])
    eye = np.eye(m)
    a_ub = np.block([[c_mat, -eye], [-c_mat, -eye]])
    b_ub = np.concatenate([upper, -lower])
    keep = np.isfinite(b_ub)
    bounds = [
        (lo if np.isfinite(lo) else None, hi if np.isfinite(hi) else None)
        for lo, hi in zip(lo_box, hi_box, strict=True)
    ] + [(0.0, None)] * m
    res = linprog(cost, A_ub=a_ub[keep], b_ub=b_ub[keep], bounds=bounds, method="highs")
    if not res.success:
        raise SolverError(f"the course-feasibility LP failed: {res.message}")
    return res.x[n:]


def _polish(hess, grad, c_mat, lower, upper, lo_box, hi_box, x, z):
    """Exact optimum on the active set ProxQP found (its non-zero multipliers z): the KKT
    system of the equality-constrained QP, kept if feasible and no worse."""
    n, m = x.size, c_mat.shape[0]
    full = np.vstack([c_mat, np.eye(n)])
    lows, ups = np.concatenate([lower, lo_box]), np.concatenate([upper, hi_box])
    values = full @ x
    zscale = max(1e-300, float(np.max(np.abs(z), initial=0.0)))
    active = np.flatnonzero(np.abs(z[: m + n]) > 1e-8 * zscale)
    rows, rhs = [], []
    for k in active:
        bound = ups[k] if abs(values[k] - ups[k]) <= abs(values[k] - lows[k]) else lows[k]
        if np.isfinite(bound):
            rows.append(full[k])
            rhs.append(bound)
    if rows:
        a = np.array(rows)
        kkt = np.block([[hess, a.T], [a, np.zeros((len(rows), len(rows)))]])
        cand = np.linalg.lstsq(kkt, np.concatenate([-grad, rhs]), rcond=None)[0][:n]
    else:
        cand = np.linalg.solve(hess, -grad)
    slack = 1e-9 * max(1.0, float(np.max(np.abs(values), initial=0.0)))
    feasible = np.all(full @ cand >= lows - slack) and np.all(full @ cand <= ups + slack)
    objective = 0.5 * cand @ hess @ cand + grad @ cand
    previous = 0.5 * x @ hess @ x + grad @ x
    if feasible and objective <= previous + 1e-12 * max(1.0, abs(previous)):
        return cand
    return x


def solve_inverse(
    problem: CondensedProblem,
    actuators: list[Actuator],
    previous_displacement: np.ndarray,
    *,
    regularisation: float = 1e-3,
    tolerance: float = 1e-9,
    max_iterations: int = 1000,
    course: str = "hard",
) -> InverseSolution:
    """min ||W_ea l + d_e_free||^2 + eps l^T W_aa l  s.t. effort and course bounds.

    The regularisation eps is relative: eps = regularisation * ||W_ea^T W_ea|| / ||W_aa||
    (Frobenius norms), so that it does not depend on the scene's units. ProxQP (proxsuite)
    solves the QP, then the optimum is made exact on the active set it found.

    Bounds that admit no solution: with course="hard" they raise InfeasibleProblemError; with
    course="soft" (what closed-loop controllers use: a cable that the dynamics carried past its
    course cannot be pulled back by a tension) the course bounds are widened by the least
    amount that makes them feasible (an LP), with an InfeasibleCourseWarning.
    """
    if course not in ("hard", "soft"):
        raise InfeasibleProblemError(f"course must be 'hard' or 'soft', got {course!r}")
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
    lo, hi, dmin, dmax = actuator_bounds(actuators, previous_displacement)
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
    lower, upper = dmin - da_free, dmax - da_free
    c_mat = w_aa / c
    lo_box, hi_box = lo * c, hi * c
    mu, z, status, iterations = _proxqp(
        hess, grad, c_mat, lower, upper, lo_box, hi_box, tolerance, max_iterations
    )
    if status != proxqp.QPSolverOutput.PROXQP_SOLVED:
        relax = _course_relaxation(c_mat, lower, upper, lo_box, hi_box)
        finite = np.abs(np.concatenate([lower, upper]))
        size = max(1.0, float(np.max(finite[np.isfinite(finite)], initial=0.0)))
        if not np.any(relax > 1e-9 * size):
            raise SolverError(f"ProxQP did not solve the inverse problem: {status}")
        worst = int(np.argmax(relax))
        message = (
            f"the course bounds cannot be met with the effort bounds at this step:"
            f" {actuators[worst].name} is {relax[worst]:.3g} outside its course"
        )
        if course == "hard":
            raise InfeasibleProblemError(message)
        warnings.warn(
            message + "; course widened by that much", InfeasibleCourseWarning, stacklevel=3
        )
        lower, upper = lower - relax * (1 + 1e-9), upper + relax * (1 + 1e-9)
        mu, z, status, iterations = _proxqp(
            hess, grad, c_mat, lower, upper, lo_box, hi_box, tolerance, max_iterations
        )
        if status != proxqp.QPSolverOutput.PROXQP_SOLVED:
            raise SolverError(f"ProxQP did not solve the relaxed inverse problem: {status}")
    mu = _polish(hess, grad, c_mat, lower, upper, lo_box, hi_box, mu, z)
    lam = np.clip(mu / c, lo, hi)
    return InverseSolution(lam, w_ea @ lam + de_free, iterations)


def _dense_qp(n: int, n_eq: int, n_in: int, tolerance: float, max_iterations: int):
    """A ProxQP dense QP with box constraints, absolute tolerance only."""
    qp = proxqp.dense.QP(n, n_eq, n_in, True)
    qp.settings.eps_abs = tolerance
    qp.settings.eps_rel = 0.0
    qp.settings.max_iter = max_iterations
    return qp


def _proxqp(hess, grad, c_mat, lower, upper, lo_box, hi_box, tolerance, max_iterations):
    # proxsuite wants finite bounds: replace infinities by a bound far outside the solution.
    big = 1e20
    qp = _dense_qp(grad.size, 0, c_mat.shape[0], tolerance, max_iterations)
    qp.init(
        hess,
        grad,
        None,
        None,
        c_mat,
        np.clip(lower, -big, big),
        np.clip(upper, -big, big),
        np.clip(lo_box, -big, big),
        np.clip(hi_box, -big, big),
    )
    qp.solve()
    res = qp.results
    return res.x.copy(), res.z.copy(), res.info.status, int(res.info.iter)


@dataclass
class ContactInverseSolution:
    """lambda for every row (actuators, effectors = 0, contacts), the rounds of the contact
    active set and whether it settled."""

    forces: np.ndarray
    rounds: int
    settled: bool


def solve_inverse_with_contacts(
    problem: CondensedProblem,
    actuators: list[Actuator],
    previous_displacement: np.ndarray,
    friction: np.ndarray,
    *,
    regularisation: float = 1e-3,
    tolerance: float = 1e-9,
    max_iterations: int = 1000,
    max_rounds: int = 30,
    initial_active: np.ndarray | None = None,
) -> ContactInverseSolution:
    """Eq. 2.15 with contacts (a QP with complementarity constraints, QPCC).

    The unknowns are the actuator forces and the contact forces (normal, two tangents). The
    complementarity 0 <= delta_n _|_ lambda_n >= 0 and Coulomb's law are met by an active set
    over the contacts, one QP (ProxQP) per round, as in SoftRobots.Inverse (Coevoet et al.,
    RA-L 2017):

    * a closed contact keeps delta_n = 0 with lambda_n >= 0; it sticks (delta_t = 0) with its
      force inside the friction pyramid |lambda_ti| <= mu / sqrt(2) lambda_n, or, once the
      pyramid binds, slides (delta_t free, force on the pyramid);
    * an open contact has lambda = 0 and delta_n >= 0.

    A closed contact whose normal force the QP drives to zero opens; an open one whose gap the
    QP closes (its delta_n >= 0 constraint active) closes; a sticking one whose pyramid binds
    slides. The rounds stop when no contact changes.
    """
    sa, se, sc = (problem.slices[r] for r in ("actuator", "effector", "contact"))
    na, nc = sa.stop - sa.start, (sc.stop - sc.start) // 3
    if na == 0 or se.stop == se.start:
        raise InfeasibleProblemError("inverse control needs actuators and effectors")
    rows = np.r_[sa, sc]  # the unknowns' rows
    w = problem.compliance
    d = problem.free_distance
    w_ex, w_xx = w[se][:, rows], w[np.ix_(rows, rows)]
    lo, hi, dmin, dmax = actuator_bounds(actuators, previous_displacement)
    c = float(np.mean(np.abs(np.diag(w[sa, sa]))))
    if not c > 0:
        raise SolverError("the actuators have zero compliance: they cannot move the robot")
    hess = w_ex.T @ w_ex
    # The regularisation of solve_inverse, so that open contacts change nothing.
    w_ea, w_aa = w[se, sa], w[sa, sa]
    eps = regularisation * np.linalg.norm(w_ea.T @ w_ea) / max(np.linalg.norm(w_aa), 1e-300)
    hess = (hess + eps * 0.5 * (w_xx + w_xx.T)) / c**2
    grad = (w_ex.T @ d[se]) / c
    n = na + 3 * nc
    normal = na + 3 * np.arange(nc)
    w_rows = w[rows][:, rows] / c  # delta of the unknowns' rows = w_rows mu + d[rows]
    d_rows = d[rows]
    pyramid = np.asarray(friction, dtype=float) / np.sqrt(2.0)
    # contact states: 0 open, 1 sticking, 2 sliding
    state = (
        np.ones(nc, dtype=int)
        if initial_active is None
        else np.where(np.asarray(initial_active, dtype=bool), 1, 0)
    )
    big = 1e20
    tried_closing = np.zeros(nc, dtype=bool)
    mu = None
    for rounds in range(1, max_rounds + 1):
        eq_rows, eq_rhs, in_rows, in_lo, in_hi = [], [], [], [], []
        box_lo, box_hi = np.full(n, -big), np.full(n, big)
        box_lo[:na], box_hi[:na] = np.clip(lo * c, -big, big), np.clip(hi * c, -big, big)
        for i in range(na):  # course bounds on the actuators' displacement
            in_rows.append(w_rows[i])
            in_lo.append(max(dmin[i] - d_rows[i], -big))
            in_hi.append(min(dmax[i] - d_rows[i], big))
        for k in range(nc):
            j = normal[k]
            if state[k] == 0:
                box_lo[j : j + 3] = box_hi[j : j + 3] = 0.0
                in_rows.append(w_rows[j])
                in_lo.append(-d_rows[j])
                in_hi.append(big)
                continue
            eq_rows.append(w_rows[j])
            eq_rhs.append(-d_rows[j])
            box_lo[j] = 0.0
            if state[k] == 1:
                for t in (1, 2):
                    eq_rows.append(w_rows[j + t])
                    eq_rhs.append(-d_rows[j + t])
            for t in (1, 2):  # -p lambda_n <= lambda_t <= p lambda_n
                for sign in (1.0, -1.0):
                    row = np.zeros(n)
                    row[j + t], row[j] = sign, -pyramid[k]
                    in_rows.append(row)
                    in_lo.append(-big)
                    in_hi.append(0.0)
        # Open contacts carry no force: their unknowns are left out of the QP (fixing them by
        # equal box bounds stalls ProxQP), only their delta_n >= 0 rows stay.
        keep = np.ones(n, dtype=bool)
        for k in np.flatnonzero(state == 0):
            keep[normal[k] : normal[k] + 3] = False
        qp = _dense_qp(int(keep.sum()), len(eq_rows), len(in_rows), tolerance, max_iterations)
        qp.init(
            hess[np.ix_(keep, keep)],
            grad[keep],
            np.array(eq_rows)[:, keep] if eq_rows else None,
            np.array(eq_rhs) if eq_rows else None,
            np.array(in_rows)[:, keep],
            np.array(in_lo),
            np.array(in_hi),
            box_lo[keep],
            box_hi[keep],
        )
        qp.solve()
        if qp.results.info.status != proxqp.QPSolverOutput.PROXQP_SOLVED:
            untried = (state == 0) & ~tried_closing
            falling = untried & (d_rows[normal] < 0.0)
            if np.any(untried):
                # Open contacts that the motion carries into the obstacle (an object falling
                # on the robot) and the actuators cannot keep open: close those the free
                # motion closes, then, if that is not enough, the others (each contact once;
                # the rounds reopen those that end up pulling).
                closing = falling if np.any(falling) else untried
                state[closing] = 1
                tried_closing |= closing
                continue
            if np.any(state == 1):
                # Sticking everywhere needs more friction than the pyramids allow: let the
                # closed contacts slide and try again.
                state = np.where(state == 1, 2, state)
                continue
            if np.any(state > 0):
                # A pushing contact cannot hold a point that the motion carries away: open
                # the closed contact whose free motion leaves the obstacle most.
                closed = np.flatnonzero(state > 0)
                state[closed[np.argmax(d_rows[normal[closed]])]] = 0
                continue
            raise InfeasibleProblemError(
                f"the inverse problem with {nc} contacts has no solution for the contact states"
                f" of round {rounds} (ProxQP: {qp.results.info.status})"
            )
        mu = np.zeros(n)
        mu[keep] = qp.results.x
        delta = w_rows @ mu + d_rows
        scale = tolerance * max(1.0, float(np.abs(delta).max()))
        new = state.copy()
        for k in range(nc):
            j = normal[k]
            if state[k] > 0 and mu[j] <= scale * c:
                new[k] = 0  # the QP pulls on it: it opens
            elif state[k] == 0 and delta[j] <= scale:
                new[k] = 1  # the QP pushes it into the obstacle: it closes
            elif state[k] == 1:
                tangential = np.abs(mu[j + 1 : j + 3]).max()
                if tangential >= pyramid[k] * mu[j] * (1.0 - 1e-9) and mu[j] > 0:
                    new[k] = 2
        if np.array_equal(new, state):
            break
        state = new
    if mu is None:
        raise InfeasibleProblemError(
            f"the inverse problem with {nc} contacts found no contact states with a solution in"
            f" {max_rounds} rounds"
        )
    forces = np.zeros(d.size)
    forces[rows] = mu / c
    forces[sa] = np.clip(forces[sa], lo, hi)
    return ContactInverseSolution(forces, rounds, np.array_equal(new, state))
