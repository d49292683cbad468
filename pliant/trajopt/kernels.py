"""Compiled box-DDP backward pass: the same recursion as :func:`pliant.trajopt.ddp.backward_pass`
(its NumPy reference, which the tests compare it with), for the MPC's many small solves."""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def _solve_free(h, g, x, free):
    """x_F = -H_FF^-1 (g_F + H_FB x_B) for the free set F (B: the others)."""
    idx = np.flatnonzero(free)
    bound = np.flatnonzero(~free)
    m = idx.size
    sub = np.empty((m, m))
    rhs = np.empty(m)
    for i in range(m):
        rhs[i] = -g[idx[i]]
        for j in range(bound.size):
            rhs[i] -= h[idx[i], bound[j]] * x[bound[j]]
        for j in range(m):
            sub[i, j] = h[idx[i], idx[j]]
    return idx, np.linalg.solve(sub, rhs)


@njit(cache=True)
def box_qp(h, g, lo, hi):
    """Exact minimiser of 1/2 x^T H x + g^T x on lo <= x <= hi (primal active set, as
    :func:`pliant.constraints.direct.box_qp`), and the mask of the free variables."""
    n = g.size
    x = -np.linalg.solve(h, g)
    if np.all(x >= lo) and np.all(x <= hi):
        return x, np.ones(n, dtype=np.bool_)
    x = np.minimum(np.maximum(x, lo), hi)
    at_bound = (x == lo) | (x == hi)
    for _ in range(10 * n + 10):
        free = ~at_bound
        if free.any():
            idx, target = _solve_free(h, g, x, free)
            t = 1.0
            for i in range(idx.size):
                step = target[i] - x[idx[i]]
                if step > 0.0:
                    t = min(t, (hi[idx[i]] - x[idx[i]]) / step)
                elif step < 0.0:
                    t = min(t, (lo[idx[i]] - x[idx[i]]) / step)
            blocked = False
            for i in range(idx.size):
                j = idx[i]
                x[j] += t * (target[i] - x[j])
                if t < 1.0 and (x[j] >= hi[j] or x[j] <= lo[j]):
                    x[j] = hi[j] if x[j] >= hi[j] else lo[j]
                    at_bound[j] = True
                    blocked = True
            if t < 1.0:
                if not blocked:  # round-off: pin the variable that stopped the step
                    best, pick = np.inf, -1
                    for i in range(idx.size):
                        j = idx[i]
                        gap = min(hi[j] - x[j], x[j] - lo[j])
                        if gap < best:
                            best, pick = gap, j
                    x[pick] = hi[pick] if hi[pick] - x[pick] < x[pick] - lo[pick] else lo[pick]
                    at_bound[pick] = True
                continue
        grad = h @ x + g
        worst, release = 0.0, -1
        for j in range(n):
            outward = (x[j] == lo[j] and grad[j] < 0.0) or (x[j] == hi[j] and grad[j] > 0.0)
            if at_bound[j] and lo[j] < hi[j] and outward and abs(grad[j]) > worst:
                worst, release = abs(grad[j]), j
        if release < 0:
            return x, ~at_bound
        at_bound[release] = False
    return x, ~at_bound


@njit(cache=True)
def backward_pass(xs, us, fx, fu, q, x_ref, r, u_ref, lower, upper, mu):
    """k (N, n_u), K (N, n_u, n_x), d1, d2 and the projected-gradient stationarity; lower,
    upper (N, n_u) the nodes' boxes."""
    n, n_u = us.shape
    n_x = xs.shape[1]
    k_ff = np.zeros((n, n_u))
    k_fb = np.zeros((n, n_u, n_x))
    vx = q[n] * (xs[n] - x_ref[n])
    vxx = np.diag(q[n].copy())
    d1 = 0.0
    d2 = 0.0
    worst = 0.0
    for t in range(n - 1, -1, -1):
        a = fx[t]
        b = fu[t]
        a_t = np.ascontiguousarray(a.T)
        b_t = np.ascontiguousarray(b.T)
        vxx_b = vxx @ b
        qx = q[t] * (xs[t] - x_ref[t]) + a_t @ vx
        qu = r * (us[t] - u_ref) + b_t @ vx
        qxx = a_t @ (vxx @ a)
        quu = b_t @ vxx_b
        for i in range(n_x):
            qxx[i, i] += q[t, i]
        mean = 0.0
        for i in range(n_u):
            quu[i, i] += r[i]
            mean += quu[i, i] / n_u
        qux = np.ascontiguousarray(vxx_b.T) @ a
        quu_reg = quu.copy()
        for i in range(n_u):
            quu_reg[i, i] += mu * mean
        lo = lower[t] - us[t]
        hi = upper[t] - us[t]
        du, free = box_qp(quu_reg, qu, lo, hi)
        gain = np.zeros((n_u, n_x))
        if free.any():
            idx = np.flatnonzero(free)
            m = idx.size
            sub = np.empty((m, m))
            rhs = np.empty((m, n_x))
            for i in range(m):
                rhs[i] = -qux[idx[i]]
                for j in range(m):
                    sub[i, j] = quu_reg[idx[i], idx[j]]
            part = np.linalg.solve(sub, rhs)
            for i in range(m):
                gain[idx[i]] = part[i]
        for i in range(n_u):
            g = qu[i]
            if lo[i] >= 0.0:
                g = min(g, 0.0)
            if hi[i] <= 0.0:
                g = max(g, 0.0)
            worst = max(worst, abs(g))
        k_ff[t] = du
        k_fb[t] = gain
        d1 += du @ qu
        d2 += du @ (quu @ du)
        gain_t = np.ascontiguousarray(gain.T)
        qux_t = np.ascontiguousarray(qux.T)
        gain_quu = gain_t @ quu
        vx = qx + gain_quu @ du + gain_t @ qu + qux_t @ du
        vxx = qxx + gain_quu @ gain + gain_t @ qux + qux_t @ gain
        vxx = 0.5 * (vxx + vxx.T)
    return k_ff, k_fb, d1, d2, worst
