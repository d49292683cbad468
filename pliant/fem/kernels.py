"""Compiled element kernels for linear tetrahedra.

Every kernel loops over elements; per element the deformation gradient is
F = sum_a x_a (x) g_a, with g_a the rest-shape gradients of the linear shape functions.
Forces are f_a = -V P(F) g_a. The stiffness K_s = -df/dx is applied element by element from
the first Piola-Kirchhoff differential dP(dF). 3x3 algebra is written out on preallocated
scratch arrays: small-matrix calls (``@``, ``np.linalg``) would dominate the cost. A plain
NumPy transcription used by the tests lives in :mod:`pliant.fem.reference`.

Material tags: 0 corotational with the polar rotation (tangent R K0 R^T, or exact),
1 Neo-Hookean (exact tangent), 2 corotational with SOFA's "large" edge-frame rotation (tangent
R K0 R^T, also when the exact one is asked for: see :class:`pliant.fem.material.Corotational`).
"""

from __future__ import annotations

import numba
import numpy as np
from numba import njit, prange

# Near convergence the Newton iterate's error e obeys e' ~ e^2 / 2 and a step is about the
# previous error, so a step below 1e-6 leaves an error below 1e-12.
_POLAR_TOL = 1e-6
_POLAR_MAX_ITER = 40


@njit(cache=True, inline="always")
def _inv3(a, out):
    """out = a^-1; returns det a."""
    c00 = a[1, 1] * a[2, 2] - a[1, 2] * a[2, 1]
    c01 = a[1, 2] * a[2, 0] - a[1, 0] * a[2, 2]
    c02 = a[1, 0] * a[2, 1] - a[1, 1] * a[2, 0]
    det = a[0, 0] * c00 + a[0, 1] * c01 + a[0, 2] * c02
    inv = 1.0 / det
    out[0, 0] = c00 * inv
    out[1, 0] = c01 * inv
    out[2, 0] = c02 * inv
    out[0, 1] = (a[0, 2] * a[2, 1] - a[0, 1] * a[2, 2]) * inv
    out[1, 1] = (a[0, 0] * a[2, 2] - a[0, 2] * a[2, 0]) * inv
    out[2, 1] = (a[0, 1] * a[2, 0] - a[0, 0] * a[2, 1]) * inv
    out[0, 2] = (a[0, 1] * a[1, 2] - a[0, 2] * a[1, 1]) * inv
    out[1, 2] = (a[0, 2] * a[1, 0] - a[0, 0] * a[1, 2]) * inv
    out[2, 2] = (a[0, 0] * a[1, 1] - a[0, 1] * a[1, 0]) * inv
    return det


@njit(cache=True, inline="always")
def _det3(a):
    return (
        a[0, 0] * (a[1, 1] * a[2, 2] - a[1, 2] * a[2, 1])
        - a[0, 1] * (a[1, 0] * a[2, 2] - a[1, 2] * a[2, 0])
        + a[0, 2] * (a[1, 0] * a[2, 1] - a[1, 1] * a[2, 0])
    )


@njit(cache=True, inline="always")
def _polar(f, r, work):
    """r = rotation of the polar decomposition F = R S (det F > 0).

    Higham's scaled Newton iteration X <- (z X + X^-T / z) / 2, z = |det X|^(-1/3),
    which converges quadratically (a few iterations for elastic strains).
    """
    for i in range(3):
        for j in range(3):
            r[i, j] = f[i, j]
    for _ in range(_POLAR_MAX_ITER):
        det = _inv3(r, work)
        # Determinant scaling speeds up the first iterations of strongly stretched elements;
        # near orthogonality the unscaled iteration is already quadratic.
        z = abs(det) ** (-1.0 / 3.0) if abs(det - 1.0) > 0.05 else 1.0
        diff = 0.0
        for i in range(3):
            for j in range(3):
                nxt = 0.5 * (z * r[i, j] + work[j, i] / z)
                diff = max(diff, abs(nxt - r[i, j]))
                r[i, j] = nxt
        if diff < _POLAR_TOL:
            break


@njit(cache=True)
def polar_rotation(f):
    """Rotation of the polar decomposition of a 3x3 matrix with positive determinant."""
    r = np.empty((3, 3))
    _polar(np.ascontiguousarray(f), r, np.empty((3, 3)))
    return r


@njit(cache=True, inline="always")
def _active(det, tag):
    """Whether an element contributes force and stiffness: det F > 0, or any finite det F
    for the inversion-tolerant large-frame law (tag 3), whose edge frame is a rotation
    whatever the element's orientation; its energy then pulls the element back."""
    return det > 0.0 or (tag == 3 and det == det)


@njit(cache=True, inline="always")
def _edge_frame(x, tet, q):
    """q = the edge frame of the nodes tet[0], tet[1], tet[2] (an element's first three in
    SOFA's "large" method), columns e_0, e_1, e_2: e_0 along x_1 - x_0, e_2 along
    (x_1 - x_0) x (x_2 - x_0), e_1 = e_2 x e_0."""
    a, b, c = tet[0], tet[1], tet[2]
    _frame_of(
        x[b, 0] - x[a, 0],
        x[b, 1] - x[a, 1],
        x[b, 2] - x[a, 2],
        x[c, 0] - x[a, 0],
        x[c, 1] - x[a, 1],
        x[c, 2] - x[a, 2],
        q,
    )


@njit(cache=True, inline="always")
def _frame_of(u0, u1, u2, w0, w1, w2, q):
    """q = the orthonormal frame of two vectors u, w, columns e_0, e_1, e_2: e_0 along u, e_2
    along u x w, e_1 = e_2 x e_0 (Gram-Schmidt, SOFA's "large" rotation)."""
    n0, n1, n2 = u1 * w2 - u2 * w1, u2 * w0 - u0 * w2, u0 * w1 - u1 * w0
    lu = np.sqrt(u0 * u0 + u1 * u1 + u2 * u2)
    ln = np.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
    u0, u1, u2 = u0 / lu, u1 / lu, u2 / lu
    n0, n1, n2 = n0 / ln, n1 / ln, n2 / ln
    q[0, 0], q[1, 0], q[2, 0] = u0, u1, u2
    q[0, 1], q[1, 1], q[2, 1] = n1 * u2 - n2 * u1, n2 * u0 - n0 * u2, n0 * u1 - n1 * u0
    q[0, 2], q[1, 2], q[2, 2] = n0, n1, n2


@njit(cache=True)
def edge_frames(x, tets):
    """Edge frames (m, 3, 3) of node triples (m, >= 3) at positions x (see `_edge_frame`)."""
    out = np.empty((tets.shape[0], 3, 3))
    for e in range(tets.shape[0]):
        _edge_frame(x, tets[e], out[e])
    return out


@njit(cache=True)
def rest_gradients(points, tets):
    """Signed rest volumes (m,) and shape-function gradients g (m, 4, 3) of linear tetrahedra."""
    m = tets.shape[0]
    grads = np.empty((m, 4, 3))
    vols = np.empty(m)
    dm = np.empty((3, 3))
    dminv = np.empty((3, 3))
    for e in range(m):
        for k in range(3):
            for i in range(3):
                dm[i, k] = points[tets[e, k + 1], i] - points[tets[e, 0], i]
        det = _det3(dm)
        vols[e] = det / 6.0
        if det == 0.0:
            grads[e] = 0.0
            continue
        _inv3(dm, dminv)
        for k in range(3):
            s = 0.0
            for a in range(3):
                grads[e, a + 1, k] = dminv[a, k]
                s += dminv[a, k]
            grads[e, 0, k] = -s
    return vols, grads


@njit(cache=True, inline="always")
def _chunks(m):
    """Bounds of the (at most 64) chunks of m elements that the parallel kernels share out,
    and their number."""
    n_chunks = max(1, min(m, 64))
    return np.linspace(0, m, n_chunks + 1).astype(np.int64), n_chunks


@njit(cache=True, inline="always")
def _row_dot(p, i, g, a):
    """P_i . g_a: the force on node a along i of an element of first Piola stress P."""
    return p[i, 0] * g[a, 0] + p[i, 1] * g[a, 1] + p[i, 2] * g[a, 2]


@njit(cache=True, inline="always")
def _gradient(x, tet, g, out):
    """out = sum_a x[tet[a]] (x) g[a]."""
    for i in range(3):
        for j in range(3):
            out[i, j] = (
                x[tet[0], i] * g[0, j]
                + x[tet[1], i] * g[1, j]
                + x[tet[2], i] * g[2, j]
                + x[tet[3], i] * g[3, j]
            )


@njit(cache=True, parallel=True, nogil=True)
def internal_forces(
    x,
    v,
    tets,
    grads,
    vols,
    mu,
    lam,
    tag,
    frame_nodes,
    rest_frames,
    elem_forces,
    elem_kv,
    frames,
    dets,
):
    """Element internal forces and elastic energy, and optionally K_s v.

    Writes -V P g_a into `elem_forces` (m, 4, 3) (sum them per node with `gather_nodal`), the
    linearisation frame (R for corotational, F^-1 for Neo-Hookean, F for St Venant-Kirchhoff)
    into `frames` (m, 3, 3)
    (tags 2 and 3: R = Q(x) Q(X)^T with Q the edge frame of the nodes `frame_nodes` (m, 3) and Q(X)
    read from `rest_frames`)
    and det F into `dets`. An element with det F <= 0 contributes no force (except under tag 3,
    see `_active`); its det is recorded so that the caller reports the inversion instead of a
    NaN. When `v` (n, 3) is not empty,
    also writes the element contributions of K_s v (default tangent, the one assembled) into
    `elem_kv` (m, 4, 3), in the same pass: an implicit step needs both. Returns the energy.
    """
    m = tets.shape[0]
    bounds, n_chunks = _chunks(m)
    energies = np.zeros(n_chunks)
    for c in prange(n_chunks):
        scratch = np.empty((7, 3, 3))
        energy = 0.0
        for e in range(bounds[c], bounds[c + 1]):
            energy += _element(
                e,
                x,
                v,
                tets,
                grads,
                vols,
                mu,
                lam,
                tag,
                frame_nodes,
                rest_frames,
                elem_forces,
                elem_kv,
                frames,
                dets,
                scratch,
            )
        energies[c] = energy
    return energies.sum()


@njit(cache=True, inline="always")
def _element(
    e,
    x,
    v,
    tets,
    grads,
    vols,
    mu,
    lam,
    tag,
    frame_nodes,
    rest_frames,
    elem_forces,
    elem_kv,
    frames,
    dets,
    scratch,
):
    """One element of `internal_forces` (`scratch`: (7, 3, 3)); returns its energy."""
    with_v = v.shape[0] > 0
    f, r, work, p, sig, w1, q = (
        scratch[0],
        scratch[1],
        scratch[2],
        scratch[3],
        scratch[4],
        scratch[5],
        scratch[6],
    )
    energy = 0.0
    g = grads[e]
    _gradient(x, tets[e], g, f)
    det = _det3(f)
    dets[e] = det
    if not _active(det, tag):
        elem_forces[e] = 0.0
        if with_v:
            elem_kv[e] = 0.0
        return 0.0
    if tag == 4:
        # St Venant-Kirchhoff: P = F S, S = lam tr(E) I + 2 mu E, E = (F^T F - I)/2.
        _svk_stress(f, mu[e], lam[e], sig, work)
        tr = work[0, 0] + work[1, 1] + work[2, 2]
        e2 = 0.0
        for i in range(3):
            for j in range(3):
                e2 += work[i, j] * work[i, j]
                p[i, j] = f[i, 0] * sig[0, j] + f[i, 1] * sig[1, j] + f[i, 2] * sig[2, j]
                frames[e, i, j] = f[i, j]
        energy += vols[e] * (0.5 * lam[e] * tr * tr + mu[e] * e2)
    elif tag != 1:
        if tag == 0:
            _polar(f, r, work)
        else:
            _edge_frame(x, frame_nodes[e], q)
            q0 = rest_frames[e]
            for i in range(3):
                for j in range(3):
                    r[i, j] = q[i, 0] * q0[j, 0] + q[i, 1] * q0[j, 1] + q[i, 2] * q0[j, 2]
        # S = R^T F, eps = sym(S) - I.
        for i in range(3):
            for j in range(3):
                work[i, j] = r[0, i] * f[0, j] + r[1, i] * f[1, j] + r[2, i] * f[2, j]
        tr = work[0, 0] + work[1, 1] + work[2, 2] - 3.0
        eps2 = 0.0
        for i in range(3):
            for j in range(3):
                eij = 0.5 * (work[i, j] + work[j, i]) - (1.0 if i == j else 0.0)
                eps2 += eij * eij
                sig[i, j] = 2.0 * mu[e] * eij + (lam[e] * tr if i == j else 0.0)
        for i in range(3):
            for j in range(3):
                p[i, j] = r[i, 0] * sig[0, j] + r[i, 1] * sig[1, j] + r[i, 2] * sig[2, j]
                frames[e, i, j] = r[i, j]
        energy += vols[e] * (mu[e] * eps2 + 0.5 * lam[e] * tr * tr)
    else:
        _inv3(f, work)
        lnj = np.log(det)
        c2 = 0.0
        for i in range(3):
            for j in range(3):
                c2 += f[i, j] * f[i, j]
        for i in range(3):
            for j in range(3):
                p[i, j] = mu[e] * f[i, j] + (lam[e] * lnj - mu[e]) * work[j, i]
                frames[e, i, j] = work[i, j]
        energy += vols[e] * (0.5 * mu[e] * (c2 - 3.0) - mu[e] * lnj + 0.5 * lam[e] * lnj * lnj)
    for a in range(4):
        for i in range(3):
            elem_forces[e, a, i] = -vols[e] * _row_dot(p, i, g, a)
    if with_v:
        _gradient(v, tets[e], g, work)
        _piola_differential(work, frames[e], f, det, mu[e], lam[e], tag, False, p, w1, sig)
        for a in range(4):
            for i in range(3):
                elem_kv[e, a, i] = vols[e] * _row_dot(p, i, g, a)
    return energy


def gather_nodal(elem_values, tets, incidence_ptr, incidence, out):
    """out[n] = sum of elem_values[e, a] over the (e, a) with tets[e, a] == n.

    elem_values (m, k, ...) (k nodes per element: 4 for tetrahedra, 8 for hexahedra) and out
    (n, ...) are contiguous; `incidence` lists e * k + a per node (sorted by node,
    `incidence_ptr` its CSR offsets). On several threads node-parallel, with no write conflicts;
    on one thread a scatter in element order, which streams through elem_values instead of
    reading it at random (3x faster on the Diamond's 4147 elements).
    """
    if numba.get_num_threads() > 1:
        _gather_by_node(elem_values, incidence_ptr, incidence, out)
    else:
        _scatter_by_element(elem_values, tets, out)


@njit(cache=True, nogil=True)
def _scatter_by_element(elem_values, tets, out):
    width = out.size // out.shape[0]
    k = elem_values.shape[1]
    flat = elem_values.reshape((elem_values.shape[0], k, width))
    res = out.reshape((out.shape[0], width))
    res[:] = 0.0
    for e in range(flat.shape[0]):
        for a in range(k):
            n = tets[e, a]
            for j in range(width):
                res[n, j] += flat[e, a, j]


@njit(cache=True, parallel=True, nogil=True)
def _gather_by_node(elem_values, incidence_ptr, incidence, out):
    width = out.size // out.shape[0]
    flat = elem_values.reshape((elem_values.shape[0] * elem_values.shape[1], width))
    res = out.reshape((out.shape[0], width))
    for n in prange(res.shape[0]):
        for j in range(width):
            acc = 0.0
            for k in range(incidence_ptr[n], incidence_ptr[n + 1]):
                acc += flat[incidence[k], j]
            res[n, j] = acc


@njit(cache=True, inline="always")
def _svk_stress(f, mu, lam, s, e):
    """St Venant-Kirchhoff: e = E = (F^T F - I) / 2 and s = S = lam tr(E) I + 2 mu E."""
    for i in range(3):
        for j in range(3):
            e[i, j] = 0.5 * (
                f[0, i] * f[0, j] + f[1, i] * f[1, j] + f[2, i] * f[2, j] - (1.0 if i == j else 0.0)
            )
    tr = e[0, 0] + e[1, 1] + e[2, 2]
    for i in range(3):
        for j in range(3):
            s[i, j] = 2.0 * mu * e[i, j] + (lam * tr if i == j else 0.0)


@njit(cache=True, inline="always")
def _piola_differential(df, frame, f, det, mu, lam, tag, exact, dp, w1, w2):
    """dp = dP for a variation dF of the deformation gradient (w1, w2 are scratch).

    Corotational (tags 0, 2 and 3): SOFA's tangent R (2 mu sym(R^T dF) + lam tr(R^T dF) I), plus,
    when `exact` and the rotation is polar (tag 0), the variation of R:
    (lam tr(S - I) - 2 mu) dR with dR = R [w]x and (tr(S) I - S) w = axial(R^T dF - dF^T R).
    Neo-Hookean (frame = F^-1): mu dF + (mu - lam ln J) F^-T dF^T F^-T + lam tr(F^-1 dF) F^-T.
    St Venant-Kirchhoff (tag 4, frame = F): dF S + F (lam tr(dE) I + 2 mu dE), dE = sym(F^T dF).
    """
    if tag == 4:
        fr = frame
        _svk_stress(fr, mu, lam, w2, w1)  # w2 = S
        for i in range(3):  # dp = dF S
            for j in range(3):
                dp[i, j] = df[i, 0] * w2[0, j] + df[i, 1] * w2[1, j] + df[i, 2] * w2[2, j]
        for i in range(3):  # w1 = F^T dF
            for j in range(3):
                w1[i, j] = fr[0, i] * df[0, j] + fr[1, i] * df[1, j] + fr[2, i] * df[2, j]
        tr = w1[0, 0] + w1[1, 1] + w1[2, 2]
        for i in range(3):  # w2 = dS
            for j in range(3):
                w2[i, j] = mu * (w1[i, j] + w1[j, i]) + (lam * tr if i == j else 0.0)
        for i in range(3):
            for j in range(3):
                dp[i, j] += fr[i, 0] * w2[0, j] + fr[i, 1] * w2[1, j] + fr[i, 2] * w2[2, j]
        return
    if tag != 1:
        r = frame
        for i in range(3):  # w1 = R^T dF
            for j in range(3):
                w1[i, j] = r[0, i] * df[0, j] + r[1, i] * df[1, j] + r[2, i] * df[2, j]
        tr = w1[0, 0] + w1[1, 1] + w1[2, 2]
        for i in range(3):  # w2 = 2 mu sym(w1) + lam tr I
            for j in range(3):
                w2[i, j] = mu * (w1[i, j] + w1[j, i]) + (lam * tr if i == j else 0.0)
        if exact and tag == 0:
            # 2 mu dF = 2 mu R (sym + skew)(R^T dF): the skew part completes the tangent.
            for i in range(3):
                for j in range(3):
                    w2[i, j] += mu * (w1[i, j] - w1[j, i])
            b0 = w1[2, 1] - w1[1, 2]
            b1 = w1[0, 2] - w1[2, 0]
            b2 = w1[1, 0] - w1[0, 1]
            for i in range(3):  # w1 = S = R^T F
                for j in range(3):
                    w1[i, j] = r[0, i] * f[0, j] + r[1, i] * f[1, j] + r[2, i] * f[2, j]
            trs = w1[0, 0] + w1[1, 1] + w1[2, 2]
            coef = lam * (trs - 3.0) - 2.0 * mu
            for i in range(3):  # w1 = tr(S) I - S
                for j in range(3):
                    w1[i, j] = (trs if i == j else 0.0) - w1[i, j]
            det_m = _det3(w1)
            m00 = (w1[1, 1] * w1[2, 2] - w1[1, 2] * w1[2, 1]) / det_m
            m01 = (w1[0, 2] * w1[2, 1] - w1[0, 1] * w1[2, 2]) / det_m
            m02 = (w1[0, 1] * w1[1, 2] - w1[0, 2] * w1[1, 1]) / det_m
            m10 = (w1[1, 2] * w1[2, 0] - w1[1, 0] * w1[2, 2]) / det_m
            m11 = (w1[0, 0] * w1[2, 2] - w1[0, 2] * w1[2, 0]) / det_m
            m12 = (w1[0, 2] * w1[1, 0] - w1[0, 0] * w1[1, 2]) / det_m
            m20 = (w1[1, 0] * w1[2, 1] - w1[1, 1] * w1[2, 0]) / det_m
            m21 = (w1[0, 1] * w1[2, 0] - w1[0, 0] * w1[2, 1]) / det_m
            m22 = (w1[0, 0] * w1[1, 1] - w1[0, 1] * w1[1, 0]) / det_m
            v0 = m00 * b0 + m01 * b1 + m02 * b2
            v1 = m10 * b0 + m11 * b1 + m12 * b2
            v2 = m20 * b0 + m21 * b1 + m22 * b2
            # w2 += coef [v]x, so that R w2 adds coef R [v]x = coef dR.
            w2[0, 1] -= coef * v2
            w2[0, 2] += coef * v1
            w2[1, 0] += coef * v2
            w2[1, 2] -= coef * v0
            w2[2, 0] -= coef * v1
            w2[2, 1] += coef * v0
        for i in range(3):
            for j in range(3):
                dp[i, j] = r[i, 0] * w2[0, j] + r[i, 1] * w2[1, j] + r[i, 2] * w2[2, j]
        return
    finv = frame
    lnj = np.log(det)
    tr = 0.0
    for i in range(3):
        for k in range(3):
            tr += finv[i, k] * df[k, i]
    for i in range(3):  # w1 = dF^T F^-T
        for j in range(3):
            w1[i, j] = df[0, i] * finv[j, 0] + df[1, i] * finv[j, 1] + df[2, i] * finv[j, 2]
    for i in range(3):  # w2 = F^-T w1
        for j in range(3):
            w2[i, j] = finv[0, i] * w1[0, j] + finv[1, i] * w1[1, j] + finv[2, i] * w1[2, j]
    c = mu - lam * lnj
    for i in range(3):
        for j in range(3):
            dp[i, j] = mu * df[i, j] + c * w2[i, j] + lam * tr * finv[j, i]


@njit(cache=True, parallel=True, nogil=True)
def stiffness_matvec(
    u, elem_dofs, x, tets, grads, vols, mu, lam, tag, frames, dets, exact, elem_out
):
    """Element contributions of K_s u for k free-DoF vectors at once.

    u (n_free, k); elem_dofs (m, 12) maps element DoFs to free DoFs (-1 when fixed);
    elem_out (m, 4, 3, k). K_s = -df/dx at the stored frames; gather with `gather_free`.
    """
    m = tets.shape[0]
    k = u.shape[1]
    bounds, n_chunks = _chunks(m)
    for c in prange(n_chunks):
        df = np.empty((3, 3))
        f = np.empty((3, 3))
        dp = np.empty((3, 3))
        w1 = np.empty((3, 3))
        w2 = np.empty((3, 3))
        ue = np.empty((4, 3))
        for e in range(bounds[c], bounds[c + 1]):
            if not _active(dets[e], tag):
                elem_out[e] = 0.0
                continue
            g = grads[e]
            if exact:
                _gradient(x, tets[e], g, f)
            v = vols[e]
            for col in range(k):
                for a in range(4):
                    for i in range(3):
                        d = elem_dofs[e, 3 * a + i]
                        ue[a, i] = u[d, col] if d >= 0 else 0.0
                for i in range(3):
                    for j in range(3):
                        df[i, j] = (
                            ue[0, i] * g[0, j]
                            + ue[1, i] * g[1, j]
                            + ue[2, i] * g[2, j]
                            + ue[3, i] * g[3, j]
                        )
                _piola_differential(
                    df, frames[e], f, dets[e], mu[e], lam[e], tag, exact, dp, w1, w2
                )
                for a in range(4):
                    for i in range(3):
                        elem_out[e, a, i, col] = v * _row_dot(dp, i, g, a)


@njit(cache=True, parallel=True, nogil=True)
def gather_free(elem_values, incidence_ptr, incidence, free_index, out):
    """out[free_index[3 n + i], :] = sum of elem_values[e, a, i, :] over the elements of node n."""
    k = out.shape[1]
    flat = elem_values.reshape((elem_values.shape[0] * elem_values.shape[1], 3, k))
    for n in prange(incidence_ptr.shape[0] - 1):
        for i in range(3):
            d = free_index[3 * n + i]
            if d < 0:
                continue
            for j in range(k):
                acc = 0.0
                for q in range(incidence_ptr[n], incidence_ptr[n + 1]):
                    acc += flat[incidence[q], i, j]
                out[d, j] = acc


@njit(cache=True, inline="always")
def _corotational_blocks(g, r, v, mu, lam, rg, out):
    """SOFA's corotational tangent of one element in closed form: with g'_a = R g_a,
    K_ab = V (mu (g_a . g_b) I + mu g'_b g'_a^T + lam g'_a g'_b^T), the blocks that the
    Piola differential of `_piola_differential` gives column by column (same numbers to
    round-off, a quarter of the work)."""
    for a in range(4):
        for i in range(3):
            rg[a, i] = r[i, 0] * g[a, 0] + r[i, 1] * g[a, 1] + r[i, 2] * g[a, 2]
    for a in range(4):
        for b in range(a, 4):
            dot = mu * (g[a, 0] * g[b, 0] + g[a, 1] * g[b, 1] + g[a, 2] * g[b, 2])
            for i in range(3):
                for j in range(3):
                    k = v * (mu * rg[b, i] * rg[a, j] + lam * rg[a, i] * rg[b, j])
                    if i == j:
                        k += v * dot
                    out[3 * a + i, 3 * b + j] = k
                    out[3 * b + j, 3 * a + i] = k


@njit(cache=True, parallel=True)
def element_stiffness(x, tets, grads, vols, mu, lam, tag, frames, dets, exact, blocks):
    """Element tangent stiffness matrices, blocks (m, 12, 12), node-major (a, i)."""
    m = tets.shape[0]
    bounds, n_chunks = _chunks(m)
    for c in prange(n_chunks):
        df = np.zeros((3, 3))
        f = np.empty((3, 3))
        dp = np.empty((3, 3))
        w1 = np.empty((3, 3))
        w2 = np.empty((3, 3))
        rg = np.empty((4, 3))
        for e in range(bounds[c], bounds[c + 1]):
            if not _active(dets[e], tag):
                blocks[e] = 0.0
                continue
            g = grads[e]
            v = vols[e]
            if tag == 2 or tag == 3 or (tag == 0 and not exact):
                _corotational_blocks(g, frames[e], v, mu[e], lam[e], rg, blocks[e])
                continue
            _gradient(x, tets[e], g, f)
            for b in range(4):
                for j in range(3):
                    for k in range(3):
                        df[j, k] = g[b, k]
                    _piola_differential(
                        df, frames[e], f, dets[e], mu[e], lam[e], tag, exact, dp, w1, w2
                    )
                    for k in range(3):
                        df[j, k] = 0.0
                    for a in range(4):
                        for i in range(3):
                            blocks[e, 3 * a + i, 3 * b + j] = v * _row_dot(dp, i, g, a)


@njit(cache=True, nogil=True)
def corotational_assembly(grads, vols, mu, lam, tag, frames, dets, scatter, data):
    """data[scatter[e, r, c]] += K_e[r, c]: SOFA's corotational tangent assembled element by
    element without storing the blocks (`element_stiffness` then `scatter_add` for tag 0,
    not exact; the same sums in the same order)."""
    rg = np.empty((4, 3))
    block = np.empty((12, 12))
    for e in range(grads.shape[0]):
        if not _active(dets[e], tag):
            continue
        _corotational_blocks(grads[e], frames[e], vols[e], mu[e], lam[e], rg, block)
        for r in range(12):
            for c in range(12):
                k = scatter[e, r, c]
                if k >= 0:
                    data[k] += block[r, c]


@njit(cache=True)
def scatter_add(blocks, scale, scatter, data):
    """data[scatter[e, r, c]] += scale * blocks[e, r, c] for every entry with scatter >= 0."""
    size = blocks.shape[1]
    for e in range(blocks.shape[0]):
        for r in range(size):
            for c in range(size):
                k = scatter[e, r, c]
                if k >= 0:
                    data[k] += scale * blocks[e, r, c]


@njit(cache=True, nogil=True)
def element_turns(frames, reference, out):
    """out[e] = R_e R0_e^T: how far each element frame turned since `reference` (m, 3, 3)."""
    for e in range(frames.shape[0]):
        for i in range(3):
            for j in range(3):
                out[e, i, j] = (
                    frames[e, i, 0] * reference[e, j, 0]
                    + frames[e, i, 1] * reference[e, j, 1]
                    + frames[e, i, 2] * reference[e, j, 2]
                )


@njit(cache=True, nogil=True)
def node_rotations(turns, incidence_ptr, incidence, out):
    """out[n] = the rotation of the polar decomposition of the sum of the element turns
    `turns` (m, 3, 3) over the elements of node n: its best fit (identity for a node in no
    element or whose sum is not a positive-determinant matrix)."""
    acc = np.empty((3, 3))
    work = np.empty((3, 3))
    for n in range(incidence_ptr.shape[0] - 1):
        acc[:] = 0.0
        for k in range(incidence_ptr[n], incidence_ptr[n + 1]):
            e = incidence[k] // 4
            for i in range(3):
                for j in range(3):
                    acc[i, j] += turns[e, i, j]
        if not _det3(acc) > 0.0:
            for i in range(3):
                for j in range(3):
                    out[n, i, j] = 1.0 if i == j else 0.0
            continue
        _polar(acc, out[n], work)


@njit(cache=True, nogil=True)
def warp_drift(turns, node_turns, tets, relevant):
    """max |T_e - Q_n| over the elements e and their nodes n with `relevant[n]`: how far the
    nodes' rotations `node_turns` (n, 3, 3) are from each element's turn `turns` (m, 3, 3)
    (NaN when one holds one)."""
    out = 0.0
    for e in range(tets.shape[0]):
        for a in range(4):
            n = tets[e, a]
            if not relevant[n]:
                continue
            for i in range(3):
                for j in range(3):
                    d = abs(turns[e, i, j] - node_turns[n, i, j])
                    if d != d:
                        return d
                    if d > out:
                        out = d
    return out


@njit(cache=True, nogil=True)
def max_abs_difference(a, b):
    """max |a - b| over two arrays of one shape, without the temporaries of numpy's version
    (the lagged tangent's drift test, at every step: 0.1 ms on the Diamond's frames in numpy).
    NaN when either holds one."""
    fa = a.reshape(-1)
    fb = b.reshape(-1)
    out = 0.0
    for i in range(fa.size):
        d = abs(fa[i] - fb[i])
        if d > out or d != d:
            out = d
            if d != d:
                return d
    return out


@njit(cache=True, nogil=True)
def motion_check(positions, velocities, displacement):
    """Whether every position and velocity is finite, and max |displacement| (three (n, 3)
    arrays, any strides): a step's divergence checks in one pass, without numpy's temporaries
    and per-call costs (a few microseconds a step on a small body)."""
    for a in (positions, velocities):
        for i in range(a.shape[0]):
            for j in range(a.shape[1]):
                v = a[i, j]
                if v - v != 0.0:  # NaN or inf
                    return False, 0.0
    jump = 0.0
    for i in range(displacement.shape[0]):
        for j in range(displacement.shape[1]):
            d = abs(displacement[i, j])
            if d > jump:
                jump = d
    return True, jump


@njit(cache=True, nogil=True)
def equal_2d(a, b):
    """Whether two 2-D arrays of one shape hold the same values (NaN equal to nothing, as
    ``np.array_equal``), without its temporaries: a step's test that it starts from the state
    the last step returned."""
    for i in range(a.shape[0]):
        for j in range(a.shape[1]):
            if a[i, j] != b[i, j]:  # NaN differs from itself
                return False
    return True
