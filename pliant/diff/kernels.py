"""Compiled element terms of the step adjoint for the corotational laws, in reverse mode.

Per element e, with F = sum_a x_a (x) g_a, dFw = sum_b w_b (x) g_b, R the element's rotation
(the forward linearisation's frame), S = R^T F, W = R^T dFw, C = sum_b c_b (x) g_b:

    phi_e(x_e) = sum_b c_b . (a_k (K_s w)_b - h f_b) = V <R Sigma, C>,
    Sigma = a_k (mu (W + W^T) + lam tr(W) I) + h (mu (S + S^T) + (lam tr(S - I) - 2 mu) I).

Its gradient in the element's 12 coordinates: with D = R^T C, D_s = D + D^T,

    d phi / V = <dR, G> + <dF, Hm>,
    G  = C Sigma^T + a_k mu dFw D_s + h mu F D_s + tr(D) (a_k lam dFw + h lam F),
    Hm = h mu R D_s + h lam tr(D) R,

and dF = e_i (x) g_a for coordinate i of corner a. The rotation's share <dR, G>:

* polar (tag 0): dR = R [v]x, (tr(S) I - S) v = g_a x r_i (r_i the i-th row of R), so
  <dR, G> = (g_a x r_i) . y with (tr(S) I - S)^T y = axial(R^T G);
* SOFA's large frames (tags 2, 3): R = Q(x) Q_0^T with Q the edge frame of three corners,
  <dR, G> = <dQ, G Q_0>, back-propagated through Q's normalisations and cross product.

That is one reverse sweep per element instead of twelve complex-step evaluations. The same
pass returns phi's two parts linear in the Lamé parameters (phi = mu phi_mu + lam phi_lam), the
cotangents of mu and lam. The plain reference, by complex step on
:func:`pliant.diff.elements.element_terms`, is what the tests compare with.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from pliant.fem.kernels import _inv3  # the solvers' 3x3 inverse (returns det)


@njit(cache=True, inline="always")
def _normalised_back(y, gy, norm, out):
    """out = the cotangent of x for y = x / |x| and a cotangent gy of y."""
    d = gy[0] * y[0] + gy[1] * y[1] + gy[2] * y[2]
    for i in range(3):
        out[i] = (gy[i] - d * y[i]) / norm


@njit(cache=True, inline="always")
def _edge_frame_back(x, tet, local, m, grad):
    """grad[corner] += d <Q, m> / d x_corner for the edge frame Q of corners `local` (3,)
    (columns u/|u|, n x u, n = (u x w)/|u x w|; see pliant.fem.kernels._edge_frame)."""
    a, b, c = tet[local[0]], tet[local[1]], tet[local[2]]
    u = np.empty(3)
    w = np.empty(3)
    for i in range(3):
        u[i] = x[b, i] - x[a, i]
        w[i] = x[c, i] - x[a, i]
    n = np.empty(3)
    n[0], n[1], n[2] = (
        u[1] * w[2] - u[2] * w[1],
        u[2] * w[0] - u[0] * w[2],
        u[0] * w[1] - u[1] * w[0],
    )
    lu = np.sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2])
    ln = np.sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2])
    uh = u / lu
    nh = n / ln
    # <Q, m> = uh.m0 + (nh x uh).m1 + nh.m2; (nh x uh).m1 = uh.(m1 x nh) = nh.(uh x m1).
    m0, m1, m2 = m[:, 0], m[:, 1], m[:, 2]
    g_uh = np.empty(3)
    g_nh = np.empty(3)
    g_uh[0] = m0[0] + m1[1] * nh[2] - m1[2] * nh[1]
    g_uh[1] = m0[1] + m1[2] * nh[0] - m1[0] * nh[2]
    g_uh[2] = m0[2] + m1[0] * nh[1] - m1[1] * nh[0]
    g_nh[0] = m2[0] + uh[1] * m1[2] - uh[2] * m1[1]
    g_nh[1] = m2[1] + uh[2] * m1[0] - uh[0] * m1[2]
    g_nh[2] = m2[2] + uh[0] * m1[1] - uh[1] * m1[0]
    g_u = np.empty(3)
    g_n = np.empty(3)
    _normalised_back(uh, g_uh, lu, g_u)
    _normalised_back(nh, g_nh, ln, g_n)
    # n = u x w: g_u += w x g_n, g_w = g_n x u.
    g_u[0] += w[1] * g_n[2] - w[2] * g_n[1]
    g_u[1] += w[2] * g_n[0] - w[0] * g_n[2]
    g_u[2] += w[0] * g_n[1] - w[1] * g_n[0]
    g_w0 = g_n[1] * u[2] - g_n[2] * u[1]
    g_w1 = g_n[2] * u[0] - g_n[0] * u[2]
    g_w2 = g_n[0] * u[1] - g_n[1] * u[0]
    grad[local[1], 0] += g_u[0]
    grad[local[1], 1] += g_u[1]
    grad[local[1], 2] += g_u[2]
    grad[local[2], 0] += g_w0
    grad[local[2], 1] += g_w1
    grad[local[2], 2] += g_w2
    grad[local[0], 0] -= g_u[0] + g_w0
    grad[local[0], 1] -= g_u[1] + g_w1
    grad[local[0], 2] -= g_u[2] + g_w2


@njit(cache=True, parallel=True, nogil=True)
def corotational_adjoint_terms(
    x, w, c, tets, grads, vols, mu, lam, tag, local, rest_frames, frames, dets, a_k, h, out, unit
):
    """out[e] (4, 3) = grad phi_e at the corners x[tets[e]]; unit[e] = (-phi_mu, -phi_lam)
    (see the module docstring). `w`, `c` (n, 3): the tangent's argument and the cotangent;
    `frames`, `dets`: the linearisation's rotations and det F at x; tags 0, 2, 3. An element
    that contributes no force (det F <= 0, except under tag 3) gets zeros."""
    m = tets.shape[0]
    n_chunks = max(1, min(m, 64))
    bounds = np.linspace(0, m, n_chunks + 1).astype(np.int64)
    for chunk in prange(n_chunks):
        f = np.empty((3, 3))
        dfw = np.empty((3, 3))
        cg = np.empty((3, 3))
        s = np.empty((3, 3))
        wr = np.empty((3, 3))
        d = np.empty((3, 3))
        ds = np.empty((3, 3))
        sig = np.empty((3, 3))
        gm = np.empty((3, 3))
        hm = np.empty((3, 3))
        z = np.empty((3, 3))
        mm = np.empty((3, 3))
        minv = np.empty((3, 3))
        qm = np.empty((3, 3))
        for e in range(bounds[chunk], bounds[chunk + 1]):
            det = dets[e]
            if not (det > 0.0 or (tag == 3 and det == det)):
                out[e] = 0.0
                unit[e] = 0.0
                continue
            g, r, ve = grads[e], frames[e], vols[e]
            for i in range(3):
                for j in range(3):
                    acc_f, acc_w, acc_c = 0.0, 0.0, 0.0
                    for b in range(4):
                        node = tets[e, b]
                        acc_f += x[node, i] * g[b, j]
                        acc_w += w[node, i] * g[b, j]
                        acc_c += c[node, i] * g[b, j]
                    f[i, j], dfw[i, j], cg[i, j] = acc_f, acc_w, acc_c
            for i in range(3):  # S = R^T F, W = R^T dFw, D = R^T C
                for j in range(3):
                    s[i, j] = r[0, i] * f[0, j] + r[1, i] * f[1, j] + r[2, i] * f[2, j]
                    wr[i, j] = r[0, i] * dfw[0, j] + r[1, i] * dfw[1, j] + r[2, i] * dfw[2, j]
                    d[i, j] = r[0, i] * cg[0, j] + r[1, i] * cg[1, j] + r[2, i] * cg[2, j]
            tr_s = s[0, 0] + s[1, 1] + s[2, 2]
            tr_w = wr[0, 0] + wr[1, 1] + wr[2, 2]
            tr_d = d[0, 0] + d[1, 1] + d[2, 2]
            phi_mu = 0.0
            for i in range(3):
                for j in range(3):
                    ds[i, j] = d[i, j] + d[j, i]
                    sym = a_k * (wr[i, j] + wr[j, i]) + h * (s[i, j] + s[j, i])
                    if i == j:
                        sym -= 2.0 * h
                    # <R S_mu, C> = <S_mu, D>
                    phi_mu += sym * d[i, j]
                    sig[i, j] = mu[e] * sym
                sig[i, i] += lam[e] * (a_k * tr_w + h * (tr_s - 3.0))
            unit[e, 0] = -ve * phi_mu
            unit[e, 1] = -ve * (a_k * tr_w + h * (tr_s - 3.0)) * tr_d
            for i in range(3):
                for j in range(3):
                    acc_g = cg[i, 0] * sig[j, 0] + cg[i, 1] * sig[j, 1] + cg[i, 2] * sig[j, 2]
                    acc_fw, acc_ff, acc_rr = 0.0, 0.0, 0.0
                    for k in range(3):
                        acc_fw += dfw[i, k] * ds[k, j]
                        acc_ff += f[i, k] * ds[k, j]
                        acc_rr += r[i, k] * ds[k, j]
                    gm[i, j] = (
                        acc_g
                        + mu[e] * (a_k * acc_fw + h * acc_ff)
                        + tr_d * lam[e] * (a_k * dfw[i, j] + h * f[i, j])
                    )
                    hm[i, j] = h * (mu[e] * acc_rr + lam[e] * tr_d * r[i, j])
            for a in range(4):  # the F share: <e_i (x) g_a, Hm> = (Hm g_a)_i
                for i in range(3):
                    out[e, a, i] = hm[i, 0] * g[a, 0] + hm[i, 1] * g[a, 1] + hm[i, 2] * g[a, 2]
            if tag == 0:
                for i in range(3):  # Z = R^T G
                    for j in range(3):
                        z[i, j] = r[0, i] * gm[0, j] + r[1, i] * gm[1, j] + r[2, i] * gm[2, j]
                        mm[i, j] = (tr_s if i == j else 0.0) - s[i, j]
                _inv3(mm, minv)
                z0, z1, z2 = z[2, 1] - z[1, 2], z[0, 2] - z[2, 0], z[1, 0] - z[0, 1]
                y0 = minv[0, 0] * z0 + minv[1, 0] * z1 + minv[2, 0] * z2
                y1 = minv[0, 1] * z0 + minv[1, 1] * z1 + minv[2, 1] * z2
                y2 = minv[0, 2] * z0 + minv[1, 2] * z1 + minv[2, 2] * z2
                for a in range(4):
                    for i in range(3):
                        b0 = r[i, 2] * g[a, 1] - r[i, 1] * g[a, 2]
                        b1 = r[i, 0] * g[a, 2] - r[i, 2] * g[a, 0]
                        b2 = r[i, 1] * g[a, 0] - r[i, 0] * g[a, 1]
                        out[e, a, i] += b0 * y0 + b1 * y1 + b2 * y2
            else:
                q0 = rest_frames[e]  # R = Q Q0^T: <dR, G> = <dQ, G Q0>
                for i in range(3):
                    for j in range(3):
                        qm[i, j] = gm[i, 0] * q0[0, j] + gm[i, 1] * q0[1, j] + gm[i, 2] * q0[2, j]
                _edge_frame_back(x, tets[e], local[e], qm, out[e])
            for a in range(4):
                for i in range(3):
                    out[e, a, i] *= ve
