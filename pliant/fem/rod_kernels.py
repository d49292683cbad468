"""Compiled kernels of the discrete Cosserat rod (:mod:`pliant.fem.rod`).

Element e joins nodes i and j (positions x, rotations R: material frame -> world; on a
lattice, R_i stands for R_i Q, the node's frame times the element's constant offset from it),
one-point quadrature at its middle (Simo & Vu-Quoc 1986; Crisfield 1997, ch. 17):

    Phi   = log(R_i^T R_j)              relative rotation, the same vector in frames i and j
    R_m   = R_i exp(Phi / 2)            the element's middle frame
    kappa = Phi / l                     curvature and twist (material frame)
    gamma = R_m^T (x_j - x_i) / l       shear and stretch (material frame)
    E_e   = l/2 [(gamma - gamma0)^T C (gamma - gamma0) + (kappa - kappa0)^T B (kappa - kappa0)]

with l the rest length, C = diag(k G A, k G A, E A) and B = diag(E I1, E I2, G J). Rotations
vary by spatial spins, R <- exp([dtheta]x) R, so with the left and right Jacobians of SO(3)
(exp((phi + d)^) = exp((J_l d)^) exp(phi^) = exp(phi^) exp((J_r d)^)):

    d Phi   = J_l(Phi)^-1 R_i^T (dtheta_j - dtheta_i)
    dtheta_m = dtheta_i + M (dtheta_j - dtheta_i),  M = R_m J_r(Phi/2) J_l(Phi)^-1 R_i^T / 2
    d gamma = R_m^T (dx_j - dx_i + [x_j - x_i]x dtheta_m) / l

The element's rows J_kappa, J_gamma (3 x 12, columns x_i, x_j, theta_i, theta_j) give the
exact forces (and moments) f = -l (J_gamma^T n + J_kappa^T m), n = C (gamma - gamma0),
m = B (kappa - kappa0). The default tangent is l (J_gamma^T C J_gamma + J_kappa^T B J_kappa),
symmetric positive semi-definite and exact at zero stress, the rod's analogue of SOFA's
R K0 R^T; the consistent tangent adds the stresses' terms (central differences of the exact
element forces, symmetrised: the spin derivatives' antisymmetric part is half the nodal
torque, zero at equilibrium).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

# Central-difference step of the consistent tangent: eps^(1/3) balances truncation (h^2) and
# round-off (eps / h); relative to the element length for positions, radians for rotations.
_FD_STEP = 6e-6


@njit(cache=True, inline="always")
def _skew(v, out):
    out[0, 0] = 0.0
    out[0, 1] = -v[2]
    out[0, 2] = v[1]
    out[1, 0] = v[2]
    out[1, 1] = 0.0
    out[1, 2] = -v[0]
    out[2, 0] = -v[1]
    out[2, 1] = v[0]
    out[2, 2] = 0.0


@njit(cache=True, inline="always")
def _skew_series(phi, b, c, out):
    """out = I + b [phi]x + c [phi]x^2, the form of exp and of the SO(3) Jacobians."""
    k = np.empty((3, 3))
    _skew(phi, k)
    for i in range(3):
        for j in range(3):
            kk = k[i, 0] * k[0, j] + k[i, 1] * k[1, j] + k[i, 2] * k[2, j]
            out[i, j] = (1.0 if i == j else 0.0) + b * k[i, j] + c * kk


@njit(cache=True)
def so3_exp(phi, out):
    """out = exp([phi]x) (Rodrigues; Taylor series of the coefficients at small angles)."""
    a2 = phi[0] * phi[0] + phi[1] * phi[1] + phi[2] * phi[2]
    a = math.sqrt(a2)
    if a < 1e-4:
        s = 1.0 - a2 / 6.0 + a2 * a2 / 120.0
        c = 0.5 - a2 / 24.0 + a2 * a2 / 720.0
    else:
        s = math.sin(a) / a
        c = (1.0 - math.cos(a)) / a2
    _skew_series(phi, s, c, out)


@njit(cache=True)
def so3_log(r, out):
    """out = phi with exp([phi]x) = r, |phi| <= pi."""
    cos_a = min(1.0, max(-1.0, 0.5 * (r[0, 0] + r[1, 1] + r[2, 2] - 1.0)))
    a = math.acos(cos_a)
    ax = 0.5 * (r[2, 1] - r[1, 2])
    ay = 0.5 * (r[0, 2] - r[2, 0])
    az = 0.5 * (r[1, 0] - r[0, 1])
    if a < 1e-4:
        f = 1.0 + a * a / 6.0  # axial = sin(a) u ~ (a - a^3 / 6) u
    elif math.pi - a > 1e-4:
        f = a / math.sin(a)
    else:
        # Near pi the axial part vanishes: the axis is a column of R + I = 2 u u^T.
        k = 0
        for i in range(1, 3):
            if r[i, i] > r[k, k]:
                k = i
        u0, u1, u2 = r[0, k], r[1, k], r[2, k]
        if k == 0:
            u0 += 1.0
        elif k == 1:
            u1 += 1.0
        else:
            u2 += 1.0
        norm = math.sqrt(u0 * u0 + u1 * u1 + u2 * u2)
        sign = 1.0 if ax * u0 + ay * u1 + az * u2 >= 0.0 else -1.0
        out[0] = sign * a * u0 / norm
        out[1] = sign * a * u1 / norm
        out[2] = sign * a * u2 / norm
        return
    out[0] = f * ax
    out[1] = f * ay
    out[2] = f * az


@njit(cache=True)
def left_jacobian_inverse(phi, out):
    """J_l(phi)^-1 = I - [phi]x / 2 + (1/a^2 - (1 + cos a) / (2 a sin a)) [phi]x^2."""
    a2 = phi[0] * phi[0] + phi[1] * phi[1] + phi[2] * phi[2]
    a = math.sqrt(a2)
    if a < 1e-3:
        c = 1.0 / 12.0 + a2 / 720.0 + a2 * a2 / 30240.0
    else:
        c = 1.0 / a2 - (1.0 + math.cos(a)) / (2.0 * a * math.sin(a))
    _skew_series(phi, -0.5, c, out)


@njit(cache=True)
def _right_jacobian(phi, out):
    """J_r(phi) = I - (1 - cos a)/a^2 [phi]x + (a - sin a)/a^3 [phi]x^2."""
    a2 = phi[0] * phi[0] + phi[1] * phi[1] + phi[2] * phi[2]
    a = math.sqrt(a2)
    if a < 1e-3:
        b = 0.5 - a2 / 24.0 + a2 * a2 / 720.0
        c = 1.0 / 6.0 - a2 / 120.0 + a2 * a2 / 5040.0
    else:
        b = (1.0 - math.cos(a)) / a2
        c = (a - math.sin(a)) / (a2 * a)
    _skew_series(phi, -b, c, out)


@njit(cache=True)
def _strains(xi, xj, ri, rj, length, gamma, kappa, rm):
    """gamma, kappa (material) and the middle frame rm of one element; returns nothing."""
    q = np.empty((3, 3))
    for a in range(3):
        for b in range(3):
            q[a, b] = ri[0, a] * rj[0, b] + ri[1, a] * rj[1, b] + ri[2, a] * rj[2, b]
    phi = np.empty(3)
    so3_log(q, phi)
    half = np.empty((3, 3))
    so3_exp(0.5 * phi, half)
    for a in range(3):
        for b in range(3):
            rm[a, b] = ri[a, 0] * half[0, b] + ri[a, 1] * half[1, b] + ri[a, 2] * half[2, b]
    for a in range(3):
        kappa[a] = phi[a] / length
        gamma[a] = (
            rm[0, a] * (xj[0] - xi[0]) + rm[1, a] * (xj[1] - xi[1]) + rm[2, a] * (xj[2] - xi[2])
        ) / length
    return phi


@njit(cache=True)
def _rows(xi, xj, ri, length, phi, rm, j_gamma, j_kappa):
    """The element's rows d gamma and d kappa (3 x 12 each, columns x_i, x_j, th_i, th_j)."""
    jl_inv = np.empty((3, 3))
    left_jacobian_inverse(phi, jl_inv)
    jr_half = np.empty((3, 3))
    _right_jacobian(0.5 * phi, jr_half)
    # d kappa = J_l^-1 R_i^T (dth_j - dth_i) / l
    a = np.empty((3, 3))  # J_l^-1 R_i^T
    for r in range(3):
        for c in range(3):
            a[r, c] = jl_inv[r, 0] * ri[c, 0] + jl_inv[r, 1] * ri[c, 1] + jl_inv[r, 2] * ri[c, 2]
    j_kappa[:, :] = 0.0
    for r in range(3):
        for c in range(3):
            j_kappa[r, 6 + c] = -a[r, c] / length
            j_kappa[r, 9 + c] = a[r, c] / length
    # M = R_m J_r(Phi/2) J_l^-1 R_i^T / 2; dth_m = (I - M) dth_i + M dth_j.
    t = np.empty((3, 3))
    for r in range(3):
        for c in range(3):
            t[r, c] = jr_half[r, 0] * a[0, c] + jr_half[r, 1] * a[1, c] + jr_half[r, 2] * a[2, c]
    m = np.empty((3, 3))
    for r in range(3):
        for c in range(3):
            m[r, c] = 0.5 * (rm[r, 0] * t[0, c] + rm[r, 1] * t[1, c] + rm[r, 2] * t[2, c])
    d = np.empty(3)
    for r in range(3):
        d[r] = xj[r] - xi[r]
    dx = np.empty((3, 3))
    _skew(d, dx)
    dm = np.empty((3, 3))  # [d]x M
    for r in range(3):
        for c in range(3):
            dm[r, c] = dx[r, 0] * m[0, c] + dx[r, 1] * m[1, c] + dx[r, 2] * m[2, c]
    # d gamma = R_m^T (dx_j - dx_i + [d]x ((I - M) dth_i + M dth_j)) / l
    for r in range(3):
        for c in range(3):
            rt = rm[c, r] / length  # (R_m^T)[r, c]
            j_gamma[r, c] = -rt
            j_gamma[r, 3 + c] = rt
        for c in range(3):
            s_i = 0.0
            s_j = 0.0
            for k in range(3):
                s_i += rm[k, r] * (dx[k, c] - dm[k, c])
                s_j += rm[k, r] * dm[k, c]
            j_gamma[r, 6 + c] = s_i / length
            j_gamma[r, 9 + c] = s_j / length


@njit(cache=True, inline="always")
def _strains_and_rows(xi, xj, ri, rj, length):
    """gamma, kappa, the middle frame and the rows J_gamma, J_kappa (3 x 12) of one element."""
    gamma = np.empty(3)
    kappa = np.empty(3)
    rm = np.empty((3, 3))
    phi = _strains(xi, xj, ri, rj, length, gamma, kappa, rm)
    j_gamma = np.empty((3, 12))
    j_kappa = np.empty((3, 12))
    _rows(xi, xj, ri, length, phi, rm, j_gamma, j_kappa)
    return gamma, kappa, rm, j_gamma, j_kappa


@njit(cache=True, inline="always")
def _column_dot(j_gamma, j_kappa, n, mo, c):
    """Entry c of J_gamma^T n + J_kappa^T mo."""
    return (
        j_gamma[0, c] * n[0]
        + j_gamma[1, c] * n[1]
        + j_gamma[2, c] * n[2]
        + j_kappa[0, c] * mo[0]
        + j_kappa[1, c] * mo[1]
        + j_kappa[2, c] * mo[2]
    )


@njit(cache=True)
def _element_forces(xi, xj, ri, rj, length, gamma0, kappa0, cs, bs, out, ve, kv):
    """Forces and moments (12,) of one element into out, and the Gauss-Newton tangent times
    the element's velocities `ve` (12,) into `kv` unless `ve` is empty; returns its energy,
    gamma_3 and middle frame."""
    gamma, kappa, rm, j_gamma, j_kappa = _strains_and_rows(xi, xj, ri, rj, length)
    energy = 0.0
    n = np.empty(3)
    mo = np.empty(3)
    for a in range(3):
        dg = gamma[a] - gamma0[a]
        dk = kappa[a] - kappa0[a]
        n[a] = cs[a] * dg
        mo[a] = bs[a] * dk
        energy += 0.5 * length * (cs[a] * dg * dg + bs[a] * dk * dk)
    for c in range(12):
        out[c] = -length * _column_dot(j_gamma, j_kappa, n, mo, c)
    if ve.shape[0] > 0:
        for a in range(3):
            sg = 0.0
            sk = 0.0
            for c in range(12):
                sg += j_gamma[a, c] * ve[c]
                sk += j_kappa[a, c] * ve[c]
            n[a] = length * cs[a] * sg
            mo[a] = length * bs[a] * sk
        for c in range(12):
            kv[c] = _column_dot(j_gamma, j_kappa, n, mo, c)
    return energy, gamma[2], rm


@njit(cache=True)
def node_rotations(vectors):
    """(N, 3, 3) rotation matrices of (N, 3) rotation vectors."""
    out = np.empty((vectors.shape[0], 3, 3))
    for i in range(vectors.shape[0]):
        so3_exp(vectors[i], out[i])
    return out


@njit(cache=True, inline="always")
def _ends(rot, i, j, offsets, e, ri, rj):
    """The element's frames at its two nodes: R_i Q_e0 and R_j Q_e1 (Q: the element's constant
    offsets from its nodes' frames, identity on a polyline; a spatial spin of R_i turns
    R_i Q_e0 by the same spin, so every derivative below holds unchanged)."""
    for a in range(3):
        for b in range(3):
            si = 0.0
            sj = 0.0
            for c in range(3):
                si += rot[i, a, c] * offsets[e, 0, c, b]
                sj += rot[j, a, c] * offsets[e, 1, c, b]
            ri[a, b] = si
            rj[a, b] = sj


@njit(cache=True)
def rest_strains(x, rot, elements, offsets, lengths):
    """(m, 3) gamma and (m, 3) kappa of every element at (x, rot): the rod's rest strains."""
    m = elements.shape[0]
    gamma = np.empty((m, 3))
    kappa = np.empty((m, 3))
    rm = np.empty((3, 3))
    ri = np.empty((3, 3))
    rj = np.empty((3, 3))
    for e in range(m):
        i, j = elements[e, 0], elements[e, 1]
        _ends(rot, i, j, offsets, e, ri, rj)
        _strains(x[i], x[j], ri, rj, lengths[e], gamma[e], kappa[e], rm)
    return gamma, kappa


@njit(cache=True)
def rod_forces(
    x, rot, elements, offsets, lengths, gamma0, kappa0, cs, bs, v, forces, kv, frames, stretch
):
    """Nodal forces (rows 0..N-1) and moments (rows N..2N-1) into `forces` (2N, 3), each
    element's middle frame into `frames` (m, 3, 3) and gamma_3 into `stretch` (m,); when
    `v` (2N, 3: velocities, then angular velocities) is not empty, the Gauss-Newton tangent
    times v into `kv` (2N, 3). Returns the elastic energy."""
    n = x.shape[0]
    forces[:, :] = 0.0
    with_v = v.shape[0] > 0
    if with_v:
        kv[:, :] = 0.0
    energy = 0.0
    fe = np.empty(12)
    ke = np.empty(12)
    ve = np.empty(12 if with_v else 0)
    rows = np.empty(4, dtype=np.int64)
    ri = np.empty((3, 3))
    rj = np.empty((3, 3))
    for e in range(elements.shape[0]):
        i, j = elements[e, 0], elements[e, 1]
        rows[0], rows[1], rows[2], rows[3] = i, j, n + i, n + j
        _ends(rot, i, j, offsets, e, ri, rj)
        if with_v:
            for b in range(4):
                for a in range(3):
                    ve[3 * b + a] = v[rows[b], a]
        en, g3, rm = _element_forces(
            x[i], x[j], ri, rj, lengths[e], gamma0[e], kappa0[e], cs[e], bs[e], fe, ve, ke
        )
        energy += en
        stretch[e] = g3
        frames[e] = rm
        for b in range(4):
            for a in range(3):
                forces[rows[b], a] += fe[3 * b + a]
                if with_v:
                    kv[rows[b], a] += ke[3 * b + a]
    return energy


@njit(cache=True)
def _gauss_newton_block(xi, xj, ri, rj, length, cs, bs, out):
    """l (J_gamma^T C J_gamma + J_kappa^T B J_kappa) (12 x 12) into out."""
    _, _, _, j_gamma, j_kappa = _strains_and_rows(xi, xj, ri, rj, length)
    for r in range(12):
        for c in range(12):
            s = 0.0
            for a in range(3):
                s += cs[a] * j_gamma[a, r] * j_gamma[a, c] + bs[a] * j_kappa[a, r] * j_kappa[a, c]
            out[r, c] = length * s


@njit(cache=True)
def _consistent_block(xi, xj, ri, rj, length, gamma0, kappa0, cs, bs, out):
    """-d f / d(x, theta) of one element by central differences, symmetrised, into out."""
    fp = np.empty(12)
    fm = np.empty(12)
    turn = np.empty((3, 3))
    step = np.zeros(3)
    no_velocities = np.empty(0)
    for c in range(12):
        node, axis = c // 3, c % 3
        h = _FD_STEP * (length if node < 2 else 1.0)
        for sign in range(2):
            s = h if sign == 0 else -h
            pi = xi.copy()
            pj = xj.copy()
            qi = ri.copy()
            qj = rj.copy()
            if node == 0:
                pi[axis] += s
            elif node == 1:
                pj[axis] += s
            else:
                step[:] = 0.0
                step[axis] = s
                so3_exp(step, turn)
                if node == 2:
                    qi = turn @ ri
                else:
                    qj = turn @ rj
            f = fp if sign == 0 else fm
            _element_forces(
                pi, pj, qi, qj, length, gamma0, kappa0, cs, bs, f, no_velocities, no_velocities
            )
        for r in range(12):
            out[r, c] = -(fp[r] - fm[r]) / (2.0 * h)
    for r in range(12):
        for c in range(r + 1, 12):
            s = 0.5 * (out[r, c] + out[c, r])
            out[r, c] = s
            out[c, r] = s


@njit(cache=True)
def rod_stiffness(x, rot, elements, offsets, lengths, gamma0, kappa0, cs, bs, exact, blocks):
    """Element tangent blocks (m, 12, 12), in the element DoF order x_i, x_j, theta_i,
    theta_j: the Gauss-Newton tangent, or the consistent one when `exact`."""
    ri = np.empty((3, 3))
    rj = np.empty((3, 3))
    for e in range(elements.shape[0]):
        i, j = elements[e, 0], elements[e, 1]
        _ends(rot, i, j, offsets, e, ri, rj)
        if exact:
            _consistent_block(
                x[i], x[j], ri, rj, lengths[e], gamma0[e], kappa0[e], cs[e], bs[e], blocks[e]
            )
        else:
            _gauss_newton_block(x[i], x[j], ri, rj, lengths[e], cs[e], bs[e], blocks[e])


@njit(cache=True, inline="always")
def _compose(first, second, inverse, out):
    """out[i] = log(exp(first[i]) exp(second[i])), with exp(second[i])^T when `inverse`."""
    a = np.empty((3, 3))
    b = np.empty((3, 3))
    for i in range(first.shape[0]):
        so3_exp(first[i], a)
        so3_exp(second[i], b)
        so3_log(a @ b.T if inverse else a @ b, out[i])


@njit(cache=True)
def advance_rotations(vectors, spins, out):
    """out[i] = log(exp(spins[i]) exp(vectors[i])): rotation vectors turned by spatial spins."""
    _compose(spins, vectors, False, out)


@njit(cache=True)
def rotation_differences(to, frm, out):
    """out[i] = log(exp(to[i]) exp(frm[i])^T): the spatial spin that turns frm into to."""
    _compose(to, frm, True, out)


@njit(cache=True)
def node_differences(to, frm, nodes, n_centreline, out):
    """out[i] = to[i] - frm[i] for a centreline node, the spin of :func:`rotation_differences`
    for an orientation (nodes[i] >= n_centreline): a rod's :meth:`~pliant.fem.rod.RodBody.
    difference` in one call (the drive velocities of every step)."""
    for i in range(nodes.shape[0]):
        if nodes[i] >= n_centreline:
            _compose(to[i : i + 1], frm[i : i + 1], True, out[i : i + 1])
        else:
            for j in range(3):
                out[i, j] = to[i, j] - frm[i, j]
