"""Compiled kernels of the contact solve: the projected block Gauss-Seidel sweep, the
Alart-Curnier function with its Newton derivative, and the semismooth Newton iteration judged
by the sweeps. The module friction.py holds the readable definitions and the validation; the
tests compare these kernels with plain references. (The detection kernels are in
pliant.geometry.collision_kernels.)"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True)
def matrix_summary(w):
    """(all entries finite, max |w_ij|, max |w_ij - w_ji|) of a square matrix, in one pass."""
    scale = asymmetry = 0.0
    for i in range(w.shape[0]):
        for j in range(i, w.shape[0]):
            a, b = w[i, j], w[j, i]
            if not (math.isfinite(a) and math.isfinite(b)):
                return False, math.nan, math.nan
            scale = max(scale, abs(a), abs(b))
            asymmetry = max(asymmetry, abs(a - b))
    return True, scale, asymmetry


@njit(cache=True)
def _disk_qp(a, b, c, g1, g2, radius):
    """argmin 1/2 x^T T x + g^T x subject to |x| <= radius, T = [[a, b], [b, c]] PSD.

    Interior: T x = -g. Boundary: (T + nu I) x = -g with |x| = radius, nu >= 0 (the 2D trust-
    region subproblem), found in T's eigenbasis by safeguarded Newton on the secular equation
    1/|x(nu)| - 1/radius = 0, which is nearly linear in nu (More and Sorensen, 1983).
    """
    if radius <= 0.0:
        return 0.0, 0.0
    # Eigen-decomposition of the symmetric 2x2 T: e1 <= e2, unit eigenvectors u (e1), v (e2).
    mean, diff = 0.5 * (a + c), 0.5 * (a - c)
    root = math.sqrt(diff * diff + b * b)
    e1, e2 = mean - root, mean + root
    v1, v2 = 1.0, 0.0
    if root > 0.0:
        # Two expressions of e2's eigenvector; take the better conditioned one.
        p1, p2, q1, q2 = b, e2 - a, e2 - c, b
        if math.hypot(p1, p2) < math.hypot(q1, q2):
            p1, p2 = q1, q2
        norm = math.hypot(p1, p2)
        v1, v2 = p1 / norm, p2 / norm
    u1, u2 = -v2, v1
    h1, h2 = u1 * g1 + u2 * g2, v1 * g1 + v2 * g2  # g in the eigenbasis
    scale = max(abs(e2), 1e-300)
    tiny = 1e-14 * scale
    # Minimum-norm stationary point at nu = 0 (directions of zero curvature with zero slope
    # leave the objective flat: the shortest minimiser is inside whenever any one is).
    x1 = 0.0 if abs(e1) <= tiny and h1 == 0.0 else (-h1 / e1 if e1 > tiny else math.inf)
    x2 = 0.0 if abs(e2) <= tiny and h2 == 0.0 else (-h2 / e2 if e2 > tiny else math.inf)
    if x1 * x1 + x2 * x2 <= radius * radius:
        return u1 * x1 + v1 * x2, u2 * x1 + v2 * x2
    lo, hi = 0.0, math.hypot(h1, h2) / radius  # |x(hi)| <= |g| / hi = radius
    nu = lo if e1 > tiny else hi
    y1 = y2 = 0.0
    for _ in range(100):
        y1, y2 = -h1 / (max(e1, 0.0) + nu), -h2 / (max(e2, 0.0) + nu)
        norm = math.hypot(y1, y2)
        residual = 1.0 / norm - 1.0 / radius
        if abs(residual) * radius <= 1e-15:
            break
        if residual < 0.0:
            lo = nu
        else:
            hi = nu
        slope = (y1 * y1 / (max(e1, 0.0) + nu) + y2 * y2 / (max(e2, 0.0) + nu)) / (
            norm * norm * norm
        )
        step = nu - residual / slope
        nu = step if lo < step < hi else 0.5 * (lo + hi)
    scale_to_disk = radius / math.hypot(y1, y2)
    y1, y2 = y1 * scale_to_disk, y2 * scale_to_disk
    return u1 * y1 + v1 * y2, u2 * y1 + v2 * y2


@njit(cache=True)
def _add_column(delta, w, row, change):
    """delta += W[:, row] * change, reading the symmetric W by (contiguous) rows."""
    if change != 0.0:
        for j in range(delta.shape[0]):
            delta[j] += w[row, j] * change


@njit(cache=True, inline="always")
def _within(held, lo, hi, target):
    """(held, target) where the force `held` lies in [lo, hi], else (the bound it passes, NaN)."""
    if held < lo:
        return lo, math.nan
    if held > hi:
        return hi, math.nan
    return held, target


@njit(cache=True)
def _actuator_law(rest, wii, displacement_mode, command, force_lo, force_hi, course_lo, course_hi):
    """An actuator row's force given rest = delta_i - W_ii lambda_i (its displacement without
    its own force), and the displacement that force holds, or NaN where the force is a bound or
    the command: the law of :func:`pliant.constraints.direct.solve_direct`, one row at a time.

    Displacement mode: the command clamped to the course, held by a force within its bounds.
    Force mode: the commanded force, unless it drives delta out of its course: then the force
    that holds delta on that bound, no further from the command.
    """
    if displacement_mode:
        target = min(max(command, course_lo), course_hi)
        return _within((target - rest) / wii, force_lo, force_hi, target)
    force = min(max(command, force_lo), force_hi)
    reached = wii * force + rest
    if reached > course_hi:  # the upper course bound lowers the force, down to force_lo
        return _within((course_hi - rest) / wii, force_lo, force, course_hi)
    if reached < course_lo:
        return _within((course_lo - rest) / wii, force, force_hi, course_lo)
    return force, math.nan


@njit(cache=True, inline="always")
def _actuator_row(blocks, j, w, delta, lam, tiny):
    """Actuator j of `blocks`: its row i, W_ii, and (force, displacement held or NaN) by
    :func:`_actuator_law` at delta and lambda; NaN forces where W_ii <= tiny (no force moves
    the row)."""
    rows, displacement_mode, command, force_lo, force_hi, course_lo, course_hi = blocks[:7]
    i = rows[j]
    wii = w[i, i]
    if wii <= tiny:
        return i, wii, math.nan, math.nan
    force, target = _actuator_law(
        delta[i] - wii * lam[i],
        wii,
        displacement_mode[j],
        command[j],
        force_lo[j],
        force_hi[j],
        course_lo[j],
        course_hi[j],
    )
    return i, wii, force, target


@njit(cache=True)
def _negligible(w):
    """The diagonal entry below which a row is one that no force moves (e.g. a contact on a
    fixed node): 1e-14 of the largest."""
    tiny = 0.0
    for i in range(w.shape[0]):
        tiny = max(tiny, 1e-14 * abs(w[i, i]))
    return tiny


@njit(cache=True)
def gauss_seidel(w, delta_free, lam, blocks, tolerance, max_iterations):
    """Projected block Gauss-Seidel on delta = W lambda + delta_free; `lam` is updated in place.

    `blocks`: the problem's arrays (:meth:`pliant.constraints.friction.ContactBlocks.arrays`).
    One sweep visits each actuator row, then each contact block (normal, t1, t2), and replaces
    its lambda by the exact solution of its own law with the other lambdas fixed. Returns the
    number of sweeps and the residual of the last one: the largest displacement correction
    |W_bb (lambda_b_new - lambda_b_old)|_inf that a block received.
    """
    contact_start, friction = blocks[7], blocks[8]
    delta = w @ lam + delta_free
    n_contacts = friction.shape[0]
    tiny = _negligible(w)
    residual = np.inf
    for sweep in range(max_iterations):
        residual = 0.0
        for j in range(blocks[0].shape[0]):
            i, wii, new, _ = _actuator_row(blocks, j, w, delta, lam, tiny)
            if wii <= tiny:
                continue
            change = new - lam[i]
            lam[i] = new
            _add_column(delta, w, i, change)
            residual = max(residual, abs(wii * change))
        for k in range(n_contacts):
            n = contact_start + 3 * k
            t1, t2 = n + 1, n + 2
            wnn = w[n, n]
            if wnn <= tiny:
                continue  # a row that no force can move (e.g. a contact on a fixed node)
            before_n, before_1, before_2 = delta[n], delta[t1], delta[t2]
            # Signorini: 0 <= delta_n  _|_  lambda_n >= 0.
            new_n = max(0.0, lam[n] - delta[n] / wnn)
            _add_column(delta, w, n, new_n - lam[n])
            lam[n] = new_n
            # Coulomb: lambda_t minimises the block's energy in the disk |lambda_t| <= mu lambda_n,
            # so delta_t = 0 inside (stick) or delta_t = -nu lambda_t on the rim (slip).
            a, b, c = w[t1, t1], w[t1, t2], w[t2, t2]
            g1 = delta[t1] - a * lam[t1] - b * lam[t2]
            g2 = delta[t2] - b * lam[t1] - c * lam[t2]
            new_1, new_2 = _disk_qp(a, b, c, g1, g2, friction[k] * new_n)
            _add_column(delta, w, t1, new_1 - lam[t1])
            _add_column(delta, w, t2, new_2 - lam[t2])
            lam[t1], lam[t2] = new_1, new_2
            residual = max(
                residual,
                abs(delta[n] - before_n),
                abs(delta[t1] - before_1),
                abs(delta[t2] - before_2),
            )
        if residual <= tolerance:
            return sweep + 1, residual
    return max_iterations, residual


@njit(cache=True)
def _add_row(jacobian, proximal, row, w, source, scale):
    """Row `row` of the derivative gains scale * W[source], and of the proximal term
    scale * W[source, source] on column `source`."""
    for j in range(w.shape[0]):
        jacobian[row, j] += scale * w[source, j]
    proximal[row, source] += scale * w[source, source]


@njit(cache=True)
def alart_curnier(w, delta, lam, blocks, jacobian, proximal):
    """F(lambda), zero exactly at the solutions of the contact problem, and the rows of lambda
    that a Newton step moves freely. When `jacobian` and `proximal` are (r, r), they receive an
    element J of F's Newton derivative and P, the term that replacing W by W + eps diag(W) in
    the derivatives of delta adds to it per unit eps (rho and the rows' scales kept).

    Contact k, rho = 1 / W_nn, sigma = lambda - rho delta (Alart and Curnier, CMAME 92, 1991):

        sigma_n <= 0 (open):      F = lambda
        else, normal:             F_n = rho delta_n
              |sigma_t| <= R:     F_t = rho delta_t                       (stick)
              |sigma_t| >  R:     F_t = lambda_t - R sigma_t / |sigma_t|  (slip)

    with R = mu sigma_n. For any rho > 0, F = 0 is Signorini's law and Coulomb's with the exact
    disk. Actuator row i: F_i = (delta_i - target) / W_ii where its law holds a displacement,
    else lambda_i - force (:func:`_actuator_law`). Other rows (effectors, rows that no force
    moves) keep lambda: F_i = 0 and a unit row, as Gauss-Seidel leaves them.
    """
    r = lam.shape[0]
    f = np.zeros(r)
    free = np.zeros(r, dtype=np.bool_)
    with_jacobian = jacobian.shape[0] == r
    if with_jacobian:
        jacobian[:, :] = 0.0
        proximal[:, :] = 0.0
        for i in range(r):
            jacobian[i, i] = 1.0
    contact_start, friction = blocks[7], blocks[8]
    tiny = _negligible(w)
    for j in range(blocks[0].shape[0]):
        i, wii, force, target = _actuator_row(blocks, j, w, delta, lam, tiny)
        if wii <= tiny:
            continue
        if math.isnan(target):
            f[i] = lam[i] - force
            continue
        f[i] = (delta[i] - target) / wii
        free[i] = True
        if with_jacobian:
            jacobian[i, i] = 0.0
            _add_row(jacobian, proximal, i, w, i, 1.0 / wii)
    for k in range(friction.shape[0]):
        n = contact_start + 3 * k
        t1, t2 = n + 1, n + 2
        if w[n, n] <= tiny:
            continue
        rho = 1.0 / w[n, n]
        sigma_n = lam[n] - rho * delta[n]
        if sigma_n <= 0.0:
            f[n], f[t1], f[t2] = lam[n], lam[t1], lam[t2]
            continue
        free[n] = free[t1] = free[t2] = True
        f[n] = rho * delta[n]
        s1, s2 = lam[t1] - rho * delta[t1], lam[t2] - rho * delta[t2]
        radius = friction[k] * sigma_n
        norm = math.hypot(s1, s2)
        if with_jacobian:
            jacobian[n, n] = 0.0
            _add_row(jacobian, proximal, n, w, n, rho)
        if norm <= radius:
            f[t1], f[t2] = rho * delta[t1], rho * delta[t2]
            if with_jacobian:
                jacobian[t1, t1] = jacobian[t2, t2] = 0.0
                _add_row(jacobian, proximal, t1, w, t1, rho)
                _add_row(jacobian, proximal, t2, w, t2, rho)
            continue
        u1, u2 = s1 / norm, s2 / norm
        f[t1], f[t2] = lam[t1] - radius * u1, lam[t2] - radius * u2
        if not with_jacobian:
            continue
        # d(R u) = u dR + (R / |sigma_t|) (I - u u^T) d sigma_t, dR = mu d sigma_n,
        # d sigma = d lambda - rho W d lambda.
        c, mu = radius / norm, friction[k]
        u = (u1, u2)
        for a in range(2):
            row = n + 1 + a
            jacobian[row, n] -= mu * u[a]
            _add_row(jacobian, proximal, row, w, n, mu * u[a] * rho)
            for b in range(2):
                projector = (1.0 if a == b else 0.0) - u[a] * u[b]  # (I - u u^T)_ab
                jacobian[row, n + 1 + b] -= c * projector
                _add_row(jacobian, proximal, row, w, n + 1 + b, c * projector * rho)
    return f, free


# The proximal weight eps of Newton's matrix J + eps P (P: the term of W + eps diag(W)) is
# adapted as a Levenberg-Marquardt parameter (More, Lecture Notes in Math. 630, 1978): divided
# by 10 after a full step, multiplied by 100 (at most twice a step) when the line search fails.
# The smallest keeps Newton exact to round-off on a well-posed problem (with one refinement,
# the error is eps^2); the largest damps the steps on an indeterminate one.
PROXIMAL_MIN, PROXIMAL_MAX = 1e-8, 1e-2
# Armijo's line search: sufficient decrease 1e-4 of |F|^2 per unit step, steps down to 2^-13.
ARMIJO, SHORTEST_STEP = 1e-4, 1e-4
#: Newton steps only on problems of at most this many rows: a step factorises a dense r x r
#: matrix (O(r^3) time, two r x r arrays), where a Gauss-Seidel sweep costs O(r^2). Above it
#: the sweeps run alone: CatchTheObject at dt 0.1 screens 2 027 candidate contacts (6 082
#: rows), of which one or two end active; 159 sweeps solve it in 0.14 s, the Newton steps took
#: 240 s and 600 MB.
NEWTON_MAX_ROWS = 1500


@njit(cache=True)
def _newton_direction(f, free, jacobian, proximal, eps):
    """x with (J + eps P) x = -F, refined once towards J x = -F; None if singular.

    Rows outside `free` have unit rows in J (and none in P): they move by -F. The others solve
    the reduced system. Where J is invertible the refined x is J^-1 (-F) to O(eps^2); where it
    is singular (W of a rigid box on its corners, an indeterminate grasp), P selects the
    smallest move of lambda, the step of a proximal point iteration.
    """
    direction = -f
    index = np.flatnonzero(free)
    m = index.size
    if m == 0:
        return direction
    exact = np.empty((m, m))
    regularised = np.empty((m, m))
    rhs = np.empty(m)
    for a in range(m):
        i = index[a]
        value = -f[i]
        for j in range(f.shape[0]):
            if not free[j]:
                value -= jacobian[i, j] * direction[j]
        rhs[a] = value
        for b in range(m):
            exact[a, b] = jacobian[i, index[b]]
            regularised[a, b] = exact[a, b] + eps * proximal[i, index[b]]
    try:
        x = np.linalg.solve(regularised, rhs)
        x += np.linalg.solve(regularised, rhs - exact @ x)
    except Exception:  # noqa: BLE001 (numba raises a plain Exception on a singular matrix)
        return None
    if not np.all(np.isfinite(x)):
        return None
    direction[index] = x
    return direction


@njit(cache=True)
def _newton_step(w, delta_free, lam, blocks, eps, jacobian, proximal):
    """One damped Newton step on F (:func:`alart_curnier`) from lam, in place: the longest of
    1, 1/2, 1/4, ... that decreases |F|^2 by Armijo's rule, retried with a larger proximal
    weight when none does. Returns (whether lam moved, the proximal weight for the next step).
    """
    delta = w @ lam + delta_free
    f, free = alart_curnier(w, delta, lam, blocks, jacobian, proximal)
    merit = f @ f
    no_jacobian = np.empty((0, 0))
    for _ in range(3):
        direction = _newton_direction(f, free, jacobian, proximal, eps)
        if direction is not None:
            change = w @ direction
            step = 1.0
            while step >= SHORTEST_STEP:
                trial = lam + step * direction
                f_trial, _ = alart_curnier(
                    w, delta + step * change, trial, blocks, no_jacobian, no_jacobian
                )
                if f_trial @ f_trial <= (1.0 - ARMIJO * step) * merit:
                    lam[:] = trial
                    return True, max(PROXIMAL_MIN, eps / 10.0) if step == 1.0 else eps
                step *= 0.5
        if eps >= PROXIMAL_MAX:
            break
        eps = min(PROXIMAL_MAX, 100.0 * eps)
    return False, eps


@njit(cache=True)
def newton_gauss_seidel(w, delta_free, lam, blocks, tolerance, max_iterations):
    """The contact problem by semismooth Newton on F (:func:`alart_curnier`), judged by
    Gauss-Seidel; `lam` (the warm start) is updated in place.

    Each iteration makes one Gauss-Seidel sweep from lam, whose residual is the convergence
    test, then a Newton step from lam, or takes the sweep's result where the step fails (or
    where the problem has more than ``NEWTON_MAX_ROWS`` rows: plain Gauss-Seidel there).
    Returns (sweeps, Newton steps, residual of the last sweep); lam is that sweep's result.
    """
    r = lam.shape[0]
    newton = r <= NEWTON_MAX_ROWS
    size = r if newton else 0
    jacobian = np.empty((size, size))
    proximal = np.empty((size, size))
    swept = np.empty(r)
    eps = PROXIMAL_MIN
    newton_steps = 0
    sweeps, residual = 0, np.inf
    while sweeps < max_iterations:
        swept[:] = lam
        _, residual = gauss_seidel(w, delta_free, swept, blocks, tolerance, 1)
        sweeps += 1
        if residual <= tolerance or sweeps == max_iterations:
            break
        moved = False
        if newton:
            moved, eps = _newton_step(w, delta_free, lam, blocks, eps, jacobian, proximal)
        if moved:
            newton_steps += 1
        else:
            lam[:] = swept
    lam[:] = swept
    return sweeps, newton_steps, residual
