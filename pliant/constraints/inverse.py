"""Inverse problem (Eq. 2.15): actuator forces that bring the effectors to their goals."""

from __future__ import annotations

import math
import time
import warnings
from dataclasses import dataclass

import numpy as np
from scipy.optimize import Bounds, LinearConstraint, linprog, minimize

from pliant._proxsuite import proxqp
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
    else:  # lstsq: the Hessian is singular where some actuators do not reach the effectors
        cand = np.linalg.lstsq(hess, -grad, rcond=None)[0]
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
    prior: np.ndarray | None = None,
    prior_weight: float = 0.0,
) -> InverseSolution:
    """min ||W_ea l + d_e_free||^2 + eps l^T W_aa l  s.t. effort and course bounds.

    With a `prior` (the actuators' displacements wanted where the effectors do not decide)
    and `prior_weight` rho > 0, the objective gains rho' ||delta_a - prior||^2, delta_a =
    W_aa l + d_a_free the actuators' displacements after the step, rho' = rho
    ||W_ea^T W_ea|| / ||W_aa^T W_aa|| (relative, as eps): a Tikhonov term towards a
    reference actuation instead of towards zero force (:func:`prior_terms`).

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
    p_hess, p_grad = prior_terms(hess, w_aa, da_free, prior, prior_weight)
    hess = (hess + eps * 0.5 * (w_aa + w_aa.T) + p_hess) / c**2
    grad = (w_ea.T @ de_free + p_grad) / c
    lower, upper = dmin - da_free, dmax - da_free
    c_mat = w_aa / c
    lo_box, hi_box = lo * c, hi * c
    res = _solve_qp(
        hess, grad, None, None, c_mat, lower, upper, lo_box, hi_box, tolerance, max_iterations
    )
    mu, z, iterations = res.x, res.z, res.iterations
    if not res.solved:
        relax = _course_relaxation(c_mat, lower, upper, lo_box, hi_box)
        finite = np.abs(np.concatenate([lower, upper]))
        size = max(1.0, float(np.max(finite[np.isfinite(finite)], initial=0.0)))
        if not np.any(relax > 1e-9 * size):  # feasible: ProxQP lost its way (a far goal)
            mu = _bounded_least_squares(hess, grad, c_mat, lower, upper, lo_box, hi_box)
            lam = np.clip(mu / c, lo, hi)
            return InverseSolution(lam, w_ea @ lam + de_free, iterations)
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
        res = _solve_qp(
            hess, grad, None, None, c_mat, lower, upper, lo_box, hi_box, tolerance, max_iterations
        )
        mu, z, iterations = res.x, res.z, res.iterations
        if not res.solved:
            mu = _bounded_least_squares(hess, grad, c_mat, lower, upper, lo_box, hi_box)
            lam = np.clip(mu / c, lo, hi)
            return InverseSolution(lam, w_ea @ lam + de_free, iterations)
    mu = _polish(hess, grad, c_mat, lower, upper, lo_box, hi_box, mu, z)
    lam = np.clip(mu / c, lo, hi)
    return InverseSolution(lam, w_ea @ lam + de_free, iterations)


def prior_terms(
    hess: np.ndarray,
    w_a: np.ndarray,
    d_a: np.ndarray,
    prior: np.ndarray | None,
    weight: float,
    rows: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """(H, g) of the prior rho' ||W_a l + d_a - prior||^2 / 2 on the unknowns l, W_a (na, n)
    the actuators' rows of the unknowns' compliance, d_a their free displacements; rho' =
    `weight` ||hess|| / ||W_a^T W_a|| (over the unknowns `rows`, all by default), hess the
    effectors' term W_e^T W_e, so that the weight is relative and free of units. Zeros
    without a prior or with weight 0; InfeasibleProblemError for a prior of the wrong size,
    not finite, or a weight that is negative or not finite."""
    n = hess.shape[0]
    if prior is None or weight == 0.0:
        return np.zeros((n, n)), np.zeros(n)
    prior = np.asarray(prior, dtype=float)
    if prior.shape != d_a.shape or not np.all(np.isfinite(prior)):
        raise InfeasibleProblemError(
            f"the prior needs {d_a.size} finite actuator displacements, got {prior.shape}"
        )
    if not (math.isfinite(weight) and weight > 0.0):
        raise InfeasibleProblemError(f"the prior's weight must be finite and >= 0, got {weight}")
    pull = w_a.T @ w_a
    index = np.arange(n) if rows is None else rows
    scale = np.linalg.norm(pull[np.ix_(index, index)])
    rho = weight * np.linalg.norm(hess[np.ix_(index, index)]) / max(scale, 1e-300)
    return rho * pull, rho * (w_a.T @ (d_a - prior))


def _bounded_least_squares(hess, grad, c_mat, lower, upper, lo_box, hi_box) -> np.ndarray:
    """The QP's minimiser by SLSQP where ProxQP gave up on a feasible problem: a goal far out
    of reach makes the effector term dwarf the bounds, and ProxQP reports it infeasible. The
    answer is the best effort, the closest configuration the bounds allow (least squares on
    the effector error); SolverError if no point within the bounds is found."""
    scale = max(float(np.max(np.abs(hess))), float(np.max(np.abs(grad))), 1e-300)
    h, g = hess / scale, grad / scale
    start = np.clip(np.zeros(g.size), lo_box, hi_box)
    result = minimize(
        lambda x: 0.5 * x @ h @ x + g @ x,
        start,
        jac=lambda x: h @ x + g,
        method="SLSQP",
        bounds=Bounds(lo_box, hi_box),
        constraints=[LinearConstraint(c_mat, lower, upper)],
        options={"maxiter": 1000, "ftol": 1e-14},
    )
    x = np.clip(result.x, lo_box, hi_box)
    values = c_mat @ x
    finite = np.abs(np.concatenate([lower, upper, values]))
    slack = 1e-6 * max(1.0, float(np.max(finite[np.isfinite(finite)], initial=0.0)))
    if not (
        np.all(np.isfinite(x))
        and np.all(values >= lower - slack)
        and np.all(values <= upper + slack)
    ):
        raise SolverError(
            f"the inverse problem has no solution within the bounds: {result.message}"
        )
    return x


#: ProxQP's tolerance on infeasibility certificates (see _qp_settings).
INFEASIBILITY_TOLERANCE = 1e-12


def _qp_settings(qp, tolerance: float, max_iterations: int, max_inner: int | None) -> None:
    """Absolute tolerance only, and tight infeasibility certificates.

    ProxQP's infeasibility certificates are tested against 1e-4 by default, relative to the
    problem's unscaled data: on the compliance rows of a resting Multigait (45 sticking
    contacts, W ~ 1e-4 mm/N) it declared a feasible QP primal infeasible at its first
    iteration, and the QPCC then rejected the contact states the robot was in (at 1e-7 and
    1e-9 it still calls feasible rounds infeasible). A certificate must now be tight, so a
    truly infeasible QP runs out its iterations instead: :func:`_solve_qp` bounds that work.
    """
    qp.settings.eps_abs = tolerance
    qp.settings.eps_rel = 0.0
    qp.settings.max_iter = max_iterations
    if max_inner is not None:
        qp.settings.max_iter_in = max_inner
    qp.settings.eps_primal_inf = INFEASIBILITY_TOLERANCE
    qp.settings.eps_dual_inf = INFEASIBILITY_TOLERANCE


@dataclass
class _QPResult:
    x: np.ndarray
    y: np.ndarray  # equality multipliers
    z: np.ndarray  # inequality multipliers, then the box's (one per unknown)
    solved: bool
    iterations: int
    infeasible: bool = False  # a certificate (ProxQP's) or HiGHS found the constraints empty


#: The first ProxQP attempt's iterations, outer (proximal) and inner (semi-smooth Newton,
#: per outer one): the feasible rounds logged of the Multigait's frictional QPCC took at most
#: 91 outer and 379 inner iterations in all (the Trunk's transfer is bit-identical with or
#: without the first attempt). An infeasible QP, whose certificate is never tight enough to
#: fire, ran 1000 outer iterations and 4.9e5 inner ones (33 s for 140 unknowns) before; its
#: first attempt now stops after at most 100 x 100.
FIRST_OUTER, FIRST_INNER = 100, 100


def _solve_qp(
    hess, grad, eq, eq_rhs, ineq, lower, upper, box_lo, box_hi, tolerance, max_iterations
):
    """min 1/2 x H x + g x  s.t.  eq x = eq_rhs, lower <= ineq x <= upper, box_lo <= x <=
    box_hi, by ProxQP's dense backend (`eq` may be None; infinite bounds are replaced by 1e20,
    which ProxQP needs finite). ProxQP's build is the one :mod:`pliant._proxsuite` loads: the
    same answer, bit for bit, in every process.

    ProxQP first runs a bounded number of iterations (``FIRST_OUTER``, ``FIRST_INNER``). If
    that does not solve it, HiGHS (scipy's ``linprog``, a simplex with reliable
    infeasibility detection) decides whether the constraints have a point at all: if not,
    the QP is infeasible at the cost of one LP; if so, ProxQP solves it again with its full
    `max_iterations`."""
    big = 1e20
    data = (
        hess,
        grad,
        eq,
        eq_rhs,
        ineq,
        np.clip(lower, -big, big),
        np.clip(upper, -big, big),
        np.clip(box_lo, -big, big),
        np.clip(box_hi, -big, big),
    )
    if max_iterations <= FIRST_OUTER:
        return _proxqp(data, tolerance, max_iterations, None)
    res = _proxqp(data, tolerance, FIRST_OUTER, FIRST_INNER)
    if res.solved or res.infeasible:
        return res
    if not _feasible(*data[2:]):
        res.infeasible = True
        return res
    return _proxqp(data, tolerance, max_iterations, None)


def _proxqp(data, tolerance: float, max_iterations: int, max_inner: int | None) -> _QPResult:
    hess, grad, eq, eq_rhs, ineq, lower, upper, box_lo, box_hi = data
    qp = proxqp.dense.QP(grad.size, 0 if eq is None else eq.shape[0], ineq.shape[0], True)
    _qp_settings(qp, tolerance, max_iterations, max_inner)
    qp.init(hess, grad, eq, eq_rhs, ineq, lower, upper, box_lo, box_hi)
    qp.solve()
    res = qp.results
    status = res.info.status
    return _QPResult(
        res.x.copy(),
        res.y.copy(),
        res.z.copy(),
        status == proxqp.QPSolverOutput.PROXQP_SOLVED,
        int(res.info.iter),
        status == proxqp.QPSolverOutput.PROXQP_PRIMAL_INFEASIBLE,
    )


def _feasible(eq, eq_rhs, ineq, lower, upper, box_lo, box_hi) -> bool:
    """Whether eq x = eq_rhs, lower <= ineq x <= upper, box_lo <= x <= box_hi has a point
    (HiGHS on the LP of zero cost; bounds at +-1e20 are absent)."""
    big = 1e20
    rows = np.vstack([ineq, -ineq])
    rhs = np.concatenate([upper, -lower])
    keep = rhs < big
    bounds = np.column_stack(
        [np.where(box_lo <= -big, -np.inf, box_lo), np.where(box_hi >= big, np.inf, box_hi)]
    )
    result = linprog(
        np.zeros(box_lo.size),
        A_ub=rows[keep] if np.any(keep) else None,
        b_ub=rhs[keep] if np.any(keep) else None,
        A_eq=eq,
        b_eq=eq_rhs,
        bounds=bounds,
        method="highs",
    )
    return result.status != 2  # 2: infeasible; a failed LP keeps ProxQP's full attempt


@dataclass
class ContactInverseSolution:
    """lambda for every row (actuators, effectors = 0, contacts), the rounds of the contact
    active set and whether it settled."""

    forces: np.ndarray
    rounds: int
    settled: bool
    timed_out: bool = False  # the rounds stopped at the time limit


_PROBE = 2  # slip state of a tangent axis with its slip left free (0 sticks, +-1 slides)


@dataclass
class _ContactQP:
    """The QPs of the QPCC's active set: one per round, for given contact states.

    slip[k, t] is 0 (sticks: delta_t = 0, |lambda_t| <= p lambda_n), s = +-1 (slides:
    lambda_t = s p lambda_n, s delta_t <= 0) or _PROBE (delta_t free, |lambda_t| <= p
    lambda_n; used once to learn which way the QP wants an axis to slip)."""

    hess: np.ndarray  # objective on the unknowns (actuators, then 3 per contact), scaled
    grad: np.ndarray
    w_rows: np.ndarray  # delta of the unknowns' rows = w_rows mu + d_rows
    d_rows: np.ndarray
    na: int
    normal: np.ndarray  # index of each contact's normal unknown
    pyramid: np.ndarray  # mu / sqrt(2) per contact
    lo: np.ndarray  # actuator force bounds (scaled) and course bounds
    hi: np.ndarray
    dmin: np.ndarray
    dmax: np.ndarray
    tolerance: float
    max_iterations: int

    def solve(self, closed: np.ndarray, slip: np.ndarray):
        """The QP's solution (all unknowns, zero for open contacts), its multipliers and the
        rows of each contact's constraints, or None where ProxQP finds no solution."""
        hess, grad, w_rows, d_rows, na = self.hess, self.grad, self.w_rows, self.d_rows, self.na
        normal, pyramid, lo, hi = self.normal, self.pyramid, self.lo, self.hi
        dmin, dmax = self.dmin, self.dmax
        n = hess.shape[0]
        big = 1e20
        eq_rows, eq_rhs, in_rows, in_lo, in_hi = [], [], [], [], []
        stick_rows, slide_rows, gap_rows = {}, {}, {}
        box_lo, box_hi = np.full(n, -big), np.full(n, big)
        box_lo[:na], box_hi[:na] = np.clip(lo, -big, big), np.clip(hi, -big, big)
        for i in range(na):  # course bounds on the actuators' displacement
            in_rows.append(w_rows[i])
            in_lo.append(max(dmin[i] - d_rows[i], -big))
            in_hi.append(min(dmax[i] - d_rows[i], big))

        def pyramid_rows(j, t, k):
            for sign in (1.0, -1.0):
                row = np.zeros(n)
                row[j + t], row[j] = sign, -pyramid[k]
                in_rows.append(row)
                in_lo.append(-big)
                in_hi.append(0.0)

        for k, j in enumerate(normal):
            if not closed[k]:
                gap_rows[k] = len(in_rows)
                in_rows.append(w_rows[j])  # delta_n >= 0
                in_lo.append(-d_rows[j])
                in_hi.append(big)
                continue
            eq_rows.append(w_rows[j])  # delta_n = 0, lambda_n >= 0
            eq_rhs.append(-d_rows[j])
            box_lo[j] = 0.0
            if pyramid[k] == 0.0:  # frictionless: lambda_t = 0, delta_t free
                for t in (1, 2):
                    row = np.zeros(n)
                    row[j + t] = 1.0
                    eq_rows.append(row)
                    eq_rhs.append(0.0)
                continue
            for t in (1, 2):
                s = slip[k, t - 1]
                if s == 0:
                    stick_rows[k, t] = len(eq_rows)
                    eq_rows.append(w_rows[j + t])
                    eq_rhs.append(-d_rows[j + t])
                    pyramid_rows(j, t, k)
                elif s == _PROBE:
                    pyramid_rows(j, t, k)
                else:
                    row = np.zeros(n)
                    row[j + t], row[j] = 1.0, -s * pyramid[k]
                    eq_rows.append(row)
                    eq_rhs.append(0.0)
                    slide_rows[k, t] = len(in_rows)
                    in_rows.append(s * w_rows[j + t])
                    in_lo.append(-big)
                    in_hi.append(-s * d_rows[j + t])
        # Open contacts carry no force: their unknowns are left out of the QP (fixing them by
        # equal box bounds stalls ProxQP), only their delta_n >= 0 rows stay.
        keep = np.ones(n, dtype=bool)
        for k in np.flatnonzero(~closed):
            keep[normal[k] : normal[k] + 3] = False
        res = _solve_qp(
            hess[np.ix_(keep, keep)],
            grad[keep],
            np.array(eq_rows)[:, keep] if eq_rows else None,
            np.array(eq_rhs) if eq_rows else None,
            np.array(in_rows)[:, keep],
            np.array(in_lo),
            np.array(in_hi),
            box_lo[keep],
            box_hi[keep],
            self.tolerance,
            self.max_iterations,
        )
        if not res.solved:
            return None
        mu = np.zeros(n)
        mu[keep] = res.x
        return mu, res.y, res.z, stick_rows, slide_rows, gap_rows


def _settle_probe(tangent: float, normal: float, pyramid: float) -> int:
    """The state of a probed tangent axis (its slip was free, its force inside the pyramid)
    from the force the QP gave it: on the pyramid, it slides against the force's direction
    (lambda_t = s p lambda_n, s delta_t <= 0); inside, it sticks. A slip with the force inside
    the pyramid is not Coulomb's law, whichever way the free slip went: deciding by the slip
    sent every axis of a resting body, creeping by 1e-5 mm, to slide at full friction, a state
    without solution (the Multigait on the floor, friction 0.7)."""
    if normal > 0.0 and abs(tangent) >= pyramid * normal * (1.0 - 1e-6):
        return 1 if tangent > 0 else -1
    return 0


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
    initial_slip: np.ndarray | None = None,
    time_limit: float | None = None,
    prior: np.ndarray | None = None,
    prior_weight: float = 0.0,
) -> ContactInverseSolution:
    """Eq. 2.15 with contacts (a QP with complementarity constraints, QPCC).

    The unknowns are the actuator forces and the contact forces (normal, two tangents). The
    complementarity 0 <= delta_n _|_ lambda_n >= 0 and Coulomb's law (pyramid
    |lambda_ti| <= mu / sqrt(2) lambda_n, each tangent axis on its own) are met by an active
    set over the contacts, one QP (ProxQP) per round, as in SoftRobots.Inverse (Coevoet et al.,
    RA-L 2017):

    * an open contact has lambda = 0 and delta_n >= 0;
    * a closed contact keeps delta_n = 0 with lambda_n >= 0; on each tangent axis it sticks
      (delta_t = 0, force inside the pyramid) or slides with the friction force on the pyramid
      and against the slip, lambda_t = s p lambda_n with s delta_t <= 0 (without that sign the
      QP would use friction as a free propulsive force).

    From a solved round: a closed contact whose normal force the QP drives to zero opens; an
    open one whose gap the QP closes closes; a sticking axis whose pyramid binds slides; a
    sticking axis on which the objective pulls (non-zero multiplier of delta_t = 0) is probed
    once with its slip free, and then slides (against the force) if the QP put its friction on
    the pyramid, else sticks; a sliding axis whose slip the QP holds back (active
    s delta_t <= 0) sticks. A change that makes the QP
    infeasible is undone and not tried again. The rounds stop when no change is left; the
    solution is then a local one (a QPCC is not convex: a contact that the QP has no reason to
    close stays open, see thesis §3.3.2). They also stop after `max_rounds`, or once
    `time_limit` seconds have passed (one round of a dense QP over hundreds of contacts takes
    seconds): the last feasible round's forces are returned, not settled, `timed_out` set.

    `initial_active` (nc,) and `initial_slip` (nc, 2: 0 sticks, +-1 slides with
    lambda_t = +-p lambda_n) seed the contact states, e.g. from the previous step's contact
    forces; without them every contact starts closed with its slip probed.
    """
    deadline = None if time_limit is None else time.monotonic() + time_limit
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
    # The regularisation of solve_inverse, scaled on the unknowns that start active (the
    # actuators and the contacts seeded closed), so that open contacts change nothing, and an
    # effector that only the contacts move (an object, W_ea = 0) still regularises the
    # actuators' pull (antagonistic cables would grow without bound).
    closed0 = (
        np.ones(nc, dtype=bool)
        if initial_active is None
        else np.asarray(initial_active, dtype=bool)
    )
    active = np.r_[
        np.arange(na), (na + 3 * np.flatnonzero(closed0)[:, None] + np.arange(3)).ravel()
    ]
    eps = regularisation * np.linalg.norm(hess[np.ix_(active, active)])
    eps /= max(np.linalg.norm(w_xx[np.ix_(active, active)]), 1e-300)
    p_hess, p_grad = prior_terms(hess, w[sa][:, rows], d[sa], prior, prior_weight, active)
    hess = (hess + eps * 0.5 * (w_xx + w_xx.T) + p_hess) / c**2
    grad = (w_ex.T @ d[se] + p_grad) / c
    normal = na + 3 * np.arange(nc)
    w_rows = w[rows][:, rows] / c  # delta of the unknowns' rows = w_rows mu + d_rows
    d_rows = d[rows]
    pyramid = np.asarray(friction, dtype=float) / np.sqrt(2.0)
    closed = (
        np.ones(nc, dtype=bool)
        if initial_active is None
        else np.asarray(initial_active, dtype=bool).copy()
    )
    slip = np.zeros((nc, 2), dtype=int)

    qp = _ContactQP(
        hess,
        grad,
        w_rows,
        d_rows,
        na,
        normal,
        pyramid,
        lo * c,
        hi * c,
        dmin,
        dmax,
        tolerance,
        max_iterations,
    )
    solve = qp.solve

    # A first feasible state: the closed contacts' friction states of `initial_slip` (the
    # previous step's, where the caller knows them), else (or if that has no solution) their
    # slip free (probed: the rounds then make each axis stick or slide); while the QP has no
    # solution,
    # free the slip of sticking axes, open the closed contacts that the free motion opens
    # (farthest first), close those it carries into their obstacle, and as a last resort open
    # contacts one by one.
    frictional = pyramid > 0.0
    result, rounds = None, 0
    if initial_slip is not None:
        initial_slip = np.asarray(initial_slip)
        if initial_slip.shape != (nc, 2) or not np.isin(initial_slip, (-1, 0, 1)).all():
            raise SolverError(
                f"initial_slip must be ({nc}, 2) of -1, 0 or 1, got shape {initial_slip.shape}"
            )
        seeded = closed & frictional
        slip[seeded] = initial_slip.astype(int)[seeded]
        result = solve(closed, slip)
        rounds = 1
    if result is None:
        slip[closed & frictional] = _PROBE
        result = solve(closed, slip)
        rounds += 1
    tried_closing = np.zeros(nc, dtype=bool)
    while result is None and rounds < max_rounds and not _past(deadline):
        leaving = closed & (d_rows[normal] > 0.0)
        falling = ~closed & ~tried_closing & (d_rows[normal] < 0.0)
        sticking = (closed & frictional)[:, None] & (slip != _PROBE)
        if np.any(sticking):
            slip[sticking] = _PROBE
        elif np.any(leaving):
            ids = np.flatnonzero(leaving)
            closed[ids[np.argmax(d_rows[normal[ids]])]] = False
        elif np.any(falling):
            closed[falling] = True
            slip[falling & frictional] = _PROBE
            tried_closing |= falling
        elif np.any(closed):
            ids = np.flatnonzero(closed)
            closed[ids[np.argmax(d_rows[normal[ids]])]] = False
        else:
            break
        result = solve(closed, slip)
        rounds += 1
    if result is None:
        late = f" (time limit {time_limit:g} s)" if _past(deadline) else ""
        raise InfeasibleProblemError(
            f"the inverse problem with {nc} contacts found no contact states with a solution in"
            f" {rounds} rounds{late}"
        )
    rejected: set[tuple] = set()
    probed: set[tuple[int, int]] = set()
    visited = {(closed.tobytes(), slip.tobytes())}
    settled = False
    while rounds < max_rounds and not _past(deadline):
        mu, y, z, stick_rows, slide_rows, gap_rows = result
        delta = w_rows @ mu + d_rows
        scale = tolerance * max(1.0, float(np.abs(delta).max()))
        zscale = 1e-8 * max(1e-300, float(np.max(np.abs(z), initial=0.0)))
        yscale = 1e-6 * max(1e-300, float(np.max(np.abs(y), initial=0.0)))
        changes = []  # (key, contact, axis or None, new value)
        for k, j in enumerate(normal):
            if closed[k] and mu[j] <= scale * c:
                changes.append(((k, "open"), k, None, False))  # the QP pulls on it
            elif not closed[k] and delta[j] <= scale and abs(z[gap_rows[k]]) > zscale:
                changes.append(((k, "close"), k, None, True))  # the QP pushes it in
            elif closed[k] and frictional[k]:
                for t in (1, 2):
                    s = slip[k, t - 1]
                    if s == _PROBE:  # slide if the QP put the friction on the pyramid
                        to = _settle_probe(mu[j + t], mu[j], pyramid[k])
                    elif s == 0 and abs(mu[j + t]) >= pyramid[k] * mu[j] * (1 - 1e-9) > 0:
                        to = 1 if mu[j + t] > 0 else -1  # the pyramid binds
                    elif s == 0 and (k, t) not in probed and abs(y[stick_rows[k, t]]) > yscale:
                        to = _PROBE
                    elif s in (1, -1) and abs(z[slide_rows[k, t]]) > zscale:
                        to = 0  # the QP holds the slip back
                    else:
                        continue
                    changes.append(((k, t, to), k, t, to))
        changes = [ch for ch in changes if ch[0] not in rejected]
        if not changes:
            settled = True
            break
        new_closed, new_slip = closed.copy(), slip.copy()
        for _, k, t, to in changes:
            if t is None:
                new_closed[k] = to
                new_slip[k] = _PROBE if to and frictional[k] else 0
            else:
                new_slip[k, t - 1] = to
                if to == _PROBE:
                    probed.add((k, t))
        key = (new_closed.tobytes(), new_slip.tobytes())
        if key in visited:  # a degenerate cycle (a contact touching with no force): stop
            settled = True
            break
        visited.add(key)
        trial = solve(new_closed, new_slip)
        rounds += 1
        if trial is None:
            rejected.update(ch[0] for ch in changes)
            continue
        closed, slip, result = new_closed, new_slip, trial
    # A probed axis is not a contact law (its friction could push the slip along): settle
    # the ones left, sliding against their slip or sticking, or open their contacts.
    probing = closed[:, None] & (slip == _PROBE)
    if np.any(probing):
        delta = w_rows @ result[0] + d_rows
        scale = tolerance * max(1.0, float(np.abs(delta).max()))
        tk, tt = np.nonzero(probing)
        for fixed in (
            [
                _settle_probe(result[0][normal[k] + 1 + t], result[0][normal[k]], pyramid[k])
                for k, t in zip(tk, tt, strict=True)
            ],
            [0] * len(tk),
        ):
            trial_slip = slip.copy()
            trial_slip[tk, tt] = fixed
            trial = solve(closed, trial_slip)
            rounds += 1
            if trial is not None:
                slip, result = trial_slip, trial
                break
        else:
            trial_closed, trial_slip = closed.copy(), slip.copy()
            trial_closed[tk] = False
            trial_slip[tk] = 0
            trial = solve(trial_closed, trial_slip)
            rounds += 1
            if trial is None:
                raise InfeasibleProblemError(
                    f"the inverse problem with {nc} contacts found no friction states with a"
                    " solution"
                )
            closed, slip, result = trial_closed, trial_slip, trial
            settled = False
    mu = result[0]
    forces = np.zeros(d.size)
    forces[rows] = mu / c
    forces[sa] = np.clip(forces[sa], lo, hi)
    return ContactInverseSolution(forces, rounds, settled, not settled and _past(deadline))


def _past(deadline: float | None) -> bool:
    return deadline is not None and time.monotonic() > deadline
