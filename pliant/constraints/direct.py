"""Direct problem: actuator forces from commands, with effort and course bounds."""

from __future__ import annotations

import numpy as np

from pliant.constraints.base import Actuator, actuator_bounds
from pliant.constraints.condensed import CondensedProblem
from pliant.errors import InfeasibleProblemError, SolverError


def box_qp(
    hess: np.ndarray,
    grad: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
    guess: np.ndarray | None = None,
) -> np.ndarray:
    """Exact minimiser of 1/2 x^T H x + g^T x on lower <= x <= upper, H symmetric positive definite.

    Primal active-set method: the free variables solve H_FF x_F = -(g_F + H_FB x_B); bounds
    that the step would cross are added, bounds whose multiplier has the wrong sign are
    released. Finite for the small systems of actuator rows it serves. `guess` (e.g. the
    previous step's solution) seeds the active set: usually it is already the right one.
    """
    n = grad.size
    if np.any(lower > upper):
        raise InfeasibleProblemError("box bounds with lower > upper admit no solution")
    if guess is not None:
        # The guess's active set is usually still the right one: solve on it and check.
        x = np.clip(np.asarray(guess, dtype=float), lower, upper)
        at_bound = ((x == lower) & np.isfinite(lower)) | ((x == upper) & np.isfinite(upper))
        free = ~at_bound
        if not at_bound.any():  # no bound held: the unconstrained minimiser, if it is feasible
            x = np.linalg.solve(hess, -grad)
            if np.all((x >= lower) & (x <= upper)):
                return x
            x = np.clip(np.asarray(guess, dtype=float), lower, upper)
        if free.any():
            x[free] = np.linalg.solve(
                hess[np.ix_(free, free)], -(grad[free] + hess[np.ix_(free, at_bound)] @ x[at_bound])
            )
        if _optimal(hess, grad, lower, upper, x, at_bound):
            return x
    # The unconstrained minimiser is the answer whenever it is feasible.
    x = np.linalg.solve(hess, -grad)
    if np.all((x >= lower) & (x <= upper)):
        return x
    if guess is not None:
        x = np.asarray(guess, dtype=float).copy()
    x = np.clip(x, lower, upper)
    at_bound = ((x == lower) & np.isfinite(lower)) | ((x == upper) & np.isfinite(upper))
    for _ in range(10 * n + 10):
        free = ~at_bound
        if free.any():
            rhs = -(grad[free] + hess[np.ix_(free, at_bound)] @ x[at_bound])
            target = np.linalg.solve(hess[np.ix_(free, free)], rhs)
            step = target - x[free]
            # Longest feasible fraction of the step towards the free-set optimum.
            with np.errstate(divide="ignore", invalid="ignore"):
                ratio_up = np.where(step > 0, (upper[free] - x[free]) / step, np.inf)
                ratio_lo = np.where(step < 0, (lower[free] - x[free]) / step, np.inf)
            ratios = np.minimum(ratio_up, ratio_lo)
            t = min(1.0, float(ratios.min()))
            x[free] += t * step
            if t < 1.0:
                blocking = np.flatnonzero(free)[
                    np.isclose(ratios, t, rtol=1e-12, atol=0.0) | (ratios <= t)
                ]
                x[blocking] = np.where(
                    step[np.isin(np.flatnonzero(free), blocking)] > 0,
                    upper[blocking],
                    lower[blocking],
                )
                at_bound[blocking] = True
                continue
        gradient = hess @ x + grad
        wrong = at_bound & (lower < upper)
        wrong &= ((x == lower) & (gradient < 0)) | ((x == upper) & (gradient > 0))
        if not wrong.any():
            return x
        release = np.flatnonzero(wrong)[np.argmax(np.abs(gradient[wrong]))]
        at_bound[release] = False
    raise SolverError("the box-constrained QP did not converge (cycling active set)")


def _optimal(hess, grad, lower, upper, x, at_bound) -> bool:
    """KKT conditions of the box QP at x with the bounds `at_bound` active."""
    if np.any(x < lower) or np.any(x > upper):
        return False
    gradient = hess @ x + grad
    wrong = at_bound & (lower < upper)
    wrong &= ((x == lower) & (gradient < 0)) | ((x == upper) & (gradient > 0))
    return not wrong.any()


def solve_direct(
    problem: CondensedProblem,
    actuators: list[Actuator],
    previous_displacement: np.ndarray,
    *,
    previous_actuation: np.ndarray | None = None,
    tolerance: float = 1e-9,
) -> np.ndarray:
    """Actuator forces lambda_a that realise the commands within their bounds.

    Displacement commands are clamped to the course bounds (and to the largest change per
    step), then met exactly unless an effort bound binds. Force commands are clamped to the
    effort bounds; if the resulting displacement leaves its course bounds, the actuator is held
    at that bound instead. Effectors are passive (lambda_e = 0).
    """
    n = len(actuators)
    if n == 0:
        return np.zeros(0)
    sl = problem.slices["actuator"]
    w = problem.compliance[sl, sl]
    d_free = problem.free_distance[sl]
    lo, hi, dmin, dmax = actuator_bounds(actuators, previous_displacement)
    displacement_mode = np.array([a.mode == "displacement" for a in actuators])
    values = np.array([a.value for a in actuators])
    if displacement_mode.all():
        # Only displacement commands: one box QP, min 1/2 l^T W l + (d_free - target)^T l.
        return box_qp(
            w, d_free - np.clip(values, dmin, dmax), lo, hi, _matching(previous_actuation, n)
        )
    commanded = np.where(displacement_mode, 0.0, np.clip(values, lo, hi))
    # A force-controlled actuator is free (lambda = command), or held at its upper course bound
    # (+1, lambda <= command) or at its lower one (-1, lambda >= command).
    status = np.zeros(n, dtype=int)
    lam = commanded.copy()
    for _ in range(3 * n + 3):
        held = ~displacement_mode & (status != 0)
        solved = displacement_mode | held
        target = np.where(
            displacement_mode, np.clip(values, dmin, dmax), np.where(status > 0, dmax, dmin)
        )
        lo_eff = np.where(held & (status < 0), np.maximum(lo, commanded), lo)
        hi_eff = np.where(held & (status > 0), np.minimum(hi, commanded), hi)
        lam = np.where(solved, lam, commanded)
        if solved.any():
            c, f = solved, ~solved
            shift = d_free[c] + w[np.ix_(c, f)] @ lam[f] - target[c]
            guess = _matching(previous_actuation, n)
            guess = None if guess is None else guess[c]
            lam[c] = box_qp(w[np.ix_(c, c)], shift, lo_eff[c], hi_eff[c], guess)
        delta = w @ lam + d_free
        scale = tolerance * max(1.0, float(np.abs(delta).max()))
        new = status.copy()
        force = ~displacement_mode
        new[force & (status == 0) & (delta > dmax + scale)] = 1
        new[force & (status == 0) & (delta < dmin - scale)] = -1
        # A held actuator whose force came back to its command is released, unless it then
        # crosses the other course bound (checked at the next pass).
        release = held & np.isclose(lam, commanded, rtol=0.0, atol=scale)
        release &= ((status > 0) & (delta < dmax - scale)) | ((status < 0) & (delta > dmin + scale))
        new[release] = 0
        if np.array_equal(new, status):
            return lam
        status = new
    return lam


def _matching(previous_actuation: np.ndarray | None, n: int) -> np.ndarray | None:
    """The previous step's forces as a warm start, if they are for the same actuators."""
    if previous_actuation is None or previous_actuation.size != n:
        return None
    return previous_actuation
