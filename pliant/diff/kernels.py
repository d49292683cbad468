"""Compiled complex-step gradient of the step adjoint's element term (corotational laws).

Per element e, phi_e(x_e) = sum_a c_a . (a_k (K_s w)_a - h f_a)(x_e), and its gradient in the
element's 12 coordinates, one complex step x_e + i s e_j per coordinate: the same formulas as
:func:`pliant.diff.elements.element_terms` (the plain reference the tests compare with),
written out per element on scratch arrays as the solvers' kernels are (STYLE item 4). The
polar rotation's complex step is R + i s dR with its exact variation (see
:func:`pliant.diff.elements.polar_rotations`); the large frames' is the edge frame of the
perturbed corners.
"""

from __future__ import annotations

import numpy as np
from numba import njit

STEP = 1e-30


@njit(cache=True, inline="always")
def _polar_real(f, r, work):
    """r = R of F = R S by scaled Newton iterations to round-off (real)."""
    for i in range(3):
        for j in range(3):
            r[i, j] = f[i, j]
    settled = 0
    for _ in range(60):
        c00 = r[1, 1] * r[2, 2] - r[1, 2] * r[2, 1]
        c01 = r[1, 2] * r[2, 0] - r[1, 0] * r[2, 2]
        c02 = r[1, 0] * r[2, 1] - r[1, 1] * r[2, 0]
        det = r[0, 0] * c00 + r[0, 1] * c01 + r[0, 2] * c02
        # work = r^-T (cofactors over det)
        work[0, 0], work[0, 1], work[0, 2] = c00 / det, c01 / det, c02 / det
        work[1, 0] = (r[2, 1] * r[0, 2] - r[2, 2] * r[0, 1]) / det
        work[1, 1] = (r[2, 2] * r[0, 0] - r[2, 0] * r[0, 2]) / det
        work[1, 2] = (r[2, 0] * r[0, 1] - r[2, 1] * r[0, 0]) / det
        work[2, 0] = (r[0, 1] * r[1, 2] - r[0, 2] * r[1, 1]) / det
        work[2, 1] = (r[0, 2] * r[1, 0] - r[0, 0] * r[1, 2]) / det
        work[2, 2] = (r[0, 0] * r[1, 1] - r[0, 1] * r[1, 0]) / det
        z = np.cbrt(det) ** -1.0 if abs(det - 1.0) > 0.05 else 1.0
        change = 0.0
        for i in range(3):
            for j in range(3):
                nxt = 0.5 * (z * r[i, j] + work[i, j] / z)
                change = max(change, abs(nxt - r[i, j]))
                r[i, j] = nxt
        settled = settled + 1 if change < 1e-14 else 0
        if settled == 2:
            break


@njit(cache=True, inline="always")
def _edge_frame(xc, local, q):
    """Complex edge frame of corners xc (4, 3) with frame nodes `local` (3,)."""
    a, b, c = local[0], local[1], local[2]
    u = np.empty(3, np.complex128)
    w = np.empty(3, np.complex128)
    for i in range(3):
        u[i] = xc[b, i] - xc[a, i]
        w[i] = xc[c, i] - xc[a, i]
    n0 = u[1] * w[2] - u[2] * w[1]
    n1 = u[2] * w[0] - u[0] * w[2]
    n2 = u[0] * w[1] - u[1] * w[0]
    lu = np.sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2])
    ln = np.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
    u0, u1, u2 = u[0] / lu, u[1] / lu, u[2] / lu
    n0, n1, n2 = n0 / ln, n1 / ln, n2 / ln
    q[0, 0], q[1, 0], q[2, 0] = u0, u1, u2
    q[0, 1], q[1, 1], q[2, 1] = n1 * u2 - n2 * u1, n2 * u0 - n0 * u2, n0 * u1 - n1 * u0
    q[0, 2], q[1, 2], q[2, 2] = n0, n1, n2


@njit(cache=True)
def corotational_value_gradient(
    x, w, c, tets, grads, vols, mu, lam, tag, local, rest_frames, a_k, h, out
):
    """out[e] (4, 3) = grad of phi_e at the corners x[tets[e]] (see the module docstring);
    `w`, `c` (n, 3): the tangent's argument and the cotangent; tags 0, 2, 3."""
    m = tets.shape[0]
    for e in range(m):
        g = grads[e]
        xc = np.empty((4, 3), np.complex128)
        f = np.zeros((3, 3))
        for a in range(4):
            for i in range(3):
                xc[a, i] = x[tets[e, a], i]
        for i in range(3):
            for j in range(3):
                for a in range(4):
                    f[i, j] += x[tets[e, a], i] * g[a, j]
        det = (
            f[0, 0] * (f[1, 1] * f[2, 2] - f[1, 2] * f[2, 1])
            - f[0, 1] * (f[1, 0] * f[2, 2] - f[1, 2] * f[2, 0])
            + f[0, 2] * (f[1, 0] * f[2, 1] - f[1, 1] * f[2, 0])
        )
        if not (det > 0.0 or (tag == 3 and det == det)):
            out[e] = 0.0
            continue
        dfw = np.zeros((3, 3))  # sum_b w_b (x) g_b
        for i in range(3):
            for j in range(3):
                for b in range(4):
                    dfw[i, j] += w[tets[e, b], i] * g[b, j]
        r0 = np.empty((3, 3))
        minv = np.empty((3, 3))
        if tag == 0:
            work = np.empty((3, 3))
            _polar_real(f, r0, work)
            s = r0.T @ f
            tr = s[0, 0] + s[1, 1] + s[2, 2]
            mm = -s.copy()
            for i in range(3):
                mm[i, i] += tr
            minv = np.linalg.inv(mm)
        rc = np.empty((3, 3), np.complex128)
        q = np.empty((3, 3), np.complex128)
        fc = np.empty((3, 3), np.complex128)
        sc = np.empty((3, 3), np.complex128)
        w1 = np.empty((3, 3), np.complex128)
        sig = np.empty((3, 3), np.complex128)
        comb = np.empty((3, 3), np.complex128)
        for j in range(12):
            a, i = j // 3, j % 3
            for p in range(3):
                for k in range(3):
                    fc[p, k] = f[p, k] + (1j * STEP * g[a, k] if p == i else 0.0)
            if tag == 0:
                # w1 = R^T dF with dF = e_i (x) g_a: w1[p, k] = r0[i, p] g[a, k].
                b0 = r0[i, 2] * g[a, 1] - r0[i, 1] * g[a, 2]
                b1 = r0[i, 0] * g[a, 2] - r0[i, 2] * g[a, 0]
                b2 = r0[i, 1] * g[a, 0] - r0[i, 0] * g[a, 1]
                v0 = minv[0, 0] * b0 + minv[0, 1] * b1 + minv[0, 2] * b2
                v1 = minv[1, 0] * b0 + minv[1, 1] * b1 + minv[1, 2] * b2
                v2 = minv[2, 0] * b0 + minv[2, 1] * b1 + minv[2, 2] * b2
                for p in range(3):
                    rc[p, 0] = r0[p, 0] + 1j * STEP * (r0[p, 1] * v2 - r0[p, 2] * v1)
                    rc[p, 1] = r0[p, 1] + 1j * STEP * (r0[p, 2] * v0 - r0[p, 0] * v2)
                    rc[p, 2] = r0[p, 2] + 1j * STEP * (r0[p, 0] * v1 - r0[p, 1] * v0)
            else:
                xc[a, i] += 1j * STEP
                _edge_frame(xc, local[e], q)
                xc[a, i] = x[tets[e, a], i]
                q0 = rest_frames[e]
                for p in range(3):
                    for k in range(3):
                        rc[p, k] = q[p, 0] * q0[k, 0] + q[p, 1] * q0[k, 1] + q[p, 2] * q0[k, 2]
            # sc = R^T F, w1 = R^T dFw
            for p in range(3):
                for k in range(3):
                    sc[p, k] = rc[0, p] * fc[0, k] + rc[1, p] * fc[1, k] + rc[2, p] * fc[2, k]
                    w1[p, k] = rc[0, p] * dfw[0, k] + rc[1, p] * dfw[1, k] + rc[2, p] * dfw[2, k]
            treps = sc[0, 0] + sc[1, 1] + sc[2, 2] - 3.0
            trw = w1[0, 0] + w1[1, 1] + w1[2, 2]
            # a_k dP(dFw) + h P = R (a_k (mu (w1 + w1^T) + lam tr(w1) I)
            #                       + h (2 mu eps + lam tr(eps) I)), eps = sym(sc) - I
            for p in range(3):
                for k in range(3):
                    sig[p, k] = a_k * mu[e] * (w1[p, k] + w1[k, p]) + h * mu[e] * (
                        sc[p, k] + sc[k, p]
                    )
                sig[p, p] += a_k * lam[e] * trw + h * (lam[e] * treps - 2.0 * mu[e])
            for p in range(3):
                for k in range(3):
                    comb[p, k] = rc[p, 0] * sig[0, k] + rc[p, 1] * sig[1, k] + rc[p, 2] * sig[2, k]
            # phi = sum_b c_b . (a_k V dP g_b + h V P g_b)
            phi = 0.0j
            for b in range(4):
                node = tets[e, b]
                for p in range(3):
                    acc = comb[p, 0] * g[b, 0] + comb[p, 1] * g[b, 1] + comb[p, 2] * g[b, 2]
                    phi += c[node, p] * acc
            out[e, a, i] = vols[e] * phi.imag / STEP
