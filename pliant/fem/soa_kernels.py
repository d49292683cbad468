"""The corotational tetrahedron pass (polar rotation, tag 0) vectorised across elements.

:func:`pliant.fem.kernels.internal_forces` walks one element at a time: its polar
decomposition iterates until the element's own step is small, a branch per element that keeps
the compiler from computing several elements in one vector register. Here the per-element data
are stored by component (structure of arrays: the shape gradients as (12, m), the element nodes
as (4, m)) and the loop body over consecutive elements has no branch, so LLVM computes four
elements per AVX2 register: the deformation gradient, a fixed number (`POLAR_STEPS`) of
Newton steps X <- (X + X^-T) / 2 on the polar factor, the stress, the forces and, when asked,
K_s v with the same rotation. An element whose last step is not below the kernel's tolerance
(a strongly stretched or inverted element, whose determinant-scaled iteration needs more steps)
is computed again by the element-by-element code, so every element meets the tolerance of
:func:`~pliant.fem.kernels.internal_forces`; the others differ from it by round-off (the extra
steps of an element that converged sooner take its rotation closer to the polar factor).
"""

from __future__ import annotations

import numba
import numpy as np
from numba import njit, prange, types
from numba.core import cgutils
from numba.extending import intrinsic

from pliant.fem import kernels

# Unscaled Newton steps every element takes (written out in `_blocks`); while the last moves a
# rotation of the block by more than the element-by-element tolerance, the whole block takes
# another, up to `MAX_POLAR_STEPS`; an element still moving is computed again one at a time.
POLAR_STEPS = 3
MAX_POLAR_STEPS = 10
# Elements per block: the loop over a block's elements is the one LLVM vectorises.
LANES = 16
# Rows of a block's results: forces (12), K_s v (12), rotation (9), det F, energy, last step,
# deformation gradient (9).
_ROWS = 45
_KV, _R, _DET, _ENERGY, _LAST, _F = 12, 24, 33, 34, 35, 36


def soa_layout(tets: np.ndarray, grads: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The element nodes (4, m) and shape gradients (12, m), row 3 a + k holding g[:, a, k],
    laid out by component for the vectorised pass."""
    m = tets.shape[0]
    return (
        np.ascontiguousarray(np.asarray(tets, np.int64).T),
        np.ascontiguousarray(np.asarray(grads, np.float64).reshape(m, 12).T),
    )


@njit(cache=True, inline="always")
def _gradient(x, nodes, g, e):
    """The nine entries, row by row, of sum_a x[nodes[a, e]] (x) (g[3 a + k, e])_k."""
    n0, n1, n2, n3 = nodes[0, e], nodes[1, e], nodes[2, e], nodes[3, e]
    g00, g01, g02 = g[0, e], g[1, e], g[2, e]
    g10, g11, g12 = g[3, e], g[4, e], g[5, e]
    g20, g21, g22 = g[6, e], g[7, e], g[8, e]
    g30, g31, g32 = g[9, e], g[10, e], g[11, e]
    x00, x01, x02 = x[n0, 0], x[n1, 0], x[n2, 0]
    x03, x10, x11 = x[n3, 0], x[n0, 1], x[n1, 1]
    x12, x13, x20 = x[n2, 1], x[n3, 1], x[n0, 2]
    x21, x22, x23 = x[n1, 2], x[n2, 2], x[n3, 2]
    return (
        x00 * g00 + x01 * g10 + x02 * g20 + x03 * g30,
        x00 * g01 + x01 * g11 + x02 * g21 + x03 * g31,
        x00 * g02 + x01 * g12 + x02 * g22 + x03 * g32,
        x10 * g00 + x11 * g10 + x12 * g20 + x13 * g30,
        x10 * g01 + x11 * g11 + x12 * g21 + x13 * g31,
        x10 * g02 + x11 * g12 + x12 * g22 + x13 * g32,
        x20 * g00 + x21 * g10 + x22 * g20 + x23 * g30,
        x20 * g01 + x21 * g11 + x22 * g21 + x23 * g31,
        x20 * g02 + x21 * g12 + x22 * g22 + x23 * g32,
    )


@njit(cache=True, inline="always")
def _newton_step(a):
    """One step X <- (X + X^-T) / 2 of the polar iteration on X = a (row by row), and the
    largest change of an entry."""
    a00, a01, a02, a10, a11, a12, a20, a21, a22 = a
    c00 = a11 * a22 - a12 * a21
    c01 = a12 * a20 - a10 * a22
    c02 = a10 * a21 - a11 * a20
    c10 = a02 * a21 - a01 * a22
    c11 = a00 * a22 - a02 * a20
    c12 = a01 * a20 - a00 * a21
    c20 = a01 * a12 - a02 * a11
    c21 = a02 * a10 - a00 * a12
    c22 = a00 * a11 - a01 * a10
    inv = 1.0 / (a00 * c00 + a01 * c01 + a02 * c02)
    n = (
        0.5 * (a00 + c00 * inv),
        0.5 * (a01 + c01 * inv),
        0.5 * (a02 + c02 * inv),
        0.5 * (a10 + c10 * inv),
        0.5 * (a11 + c11 * inv),
        0.5 * (a12 + c12 * inv),
        0.5 * (a20 + c20 * inv),
        0.5 * (a21 + c21 * inv),
        0.5 * (a22 + c22 * inv),
    )
    d = abs(n[0] - a00)
    d = max(d, abs(n[1] - a01))
    d = max(d, abs(n[2] - a02))
    d = max(d, abs(n[3] - a10))
    d = max(d, abs(n[4] - a11))
    d = max(d, abs(n[5] - a12))
    d = max(d, abs(n[6] - a20))
    d = max(d, abs(n[7] - a21))
    d = max(d, abs(n[8] - a22))
    return n, d


@njit(cache=True, inline="always")
def _transpose_times(r, m):
    """R^T M, row by row."""
    r00, r01, r02, r10, r11, r12, r20, r21, r22 = r
    return _times((r00, r10, r20, r01, r11, r21, r02, r12, r22), m)


@njit(cache=True, inline="always")
def _times(r, w):
    """R W, row by row."""
    r00, r01, r02, r10, r11, r12, r20, r21, r22 = r
    w00, w01, w02, w10, w11, w12, w20, w21, w22 = w
    return (
        r00 * w00 + r01 * w10 + r02 * w20,
        r00 * w01 + r01 * w11 + r02 * w21,
        r00 * w02 + r01 * w12 + r02 * w22,
        r10 * w00 + r11 * w10 + r12 * w20,
        r10 * w01 + r11 * w11 + r12 * w21,
        r10 * w02 + r11 * w12 + r12 * w22,
        r20 * w00 + r21 * w10 + r22 * w20,
        r20 * w01 + r21 * w11 + r22 * w21,
        r20 * w02 + r21 * w12 + r22 * w22,
    )


@njit(cache=True, inline="always")
def _isotropic(s, mu, lam, shift):
    """mu (S + S^T) + lam (tr S - 3 shift) I - 2 mu shift I, row by row: the corotational
    stress of S = R^T F with shift 1, its differential for S = R^T dF with shift 0; and
    sum eps_ij^2 with eps = sym(S) - shift I."""
    s00, s01, s02, s10, s11, s12, s20, s21, s22 = s
    tr = s00 + s11 + s22 - 3.0 * shift
    e00 = s00 - shift
    e11 = s11 - shift
    e22 = s22 - shift
    e01 = 0.5 * (s01 + s10)
    e02 = 0.5 * (s02 + s20)
    e12 = 0.5 * (s12 + s21)
    eps2 = e00 * e00 + e11 * e11 + e22 * e22 + 2.0 * (e01 * e01 + e02 * e02 + e12 * e12)
    m2 = 2.0 * mu
    lt = lam * tr
    sig = (
        m2 * e00 + lt,
        m2 * e01,
        m2 * e02,
        m2 * e01,
        m2 * e11 + lt,
        m2 * e12,
        m2 * e02,
        m2 * e12,
        m2 * e22 + lt,
    )
    return sig, tr, eps2


@intrinsic
def _block_buffer(typingctx):
    """A (_ROWS * LANES,) float64 array on the stack. The block's results go there first: LLVM
    knows that it overlaps no argument, so the loop over the block needs no run-time check of
    its stores against the loads of positions and gradients (which it could not bound)."""

    def codegen(context, builder, signature, args):
        ty = context.get_value_type(types.float64)
        size = context.get_constant(types.intp, _ROWS * LANES)
        return cgutils.alloca_once(builder, ty, size=size)

    return types.CPointer(types.float64)(), codegen


@njit(cache=True, inline="always")
def _put_node(buf, k, p, ga0, ga1, ga2, scale):
    """buf[k + i LANES] = scale P_i . g_a for i = 0, 1, 2."""
    buf[k] = scale * (p[0] * ga0 + p[1] * ga1 + p[2] * ga2)
    buf[k + LANES] = scale * (p[3] * ga0 + p[4] * ga1 + p[5] * ga2)
    buf[k + 2 * LANES] = scale * (p[6] * ga0 + p[7] * ga1 + p[8] * ga2)


@njit(cache=True, inline="always")
def _put_nodal(buf, row, l, p, g, e, scale):
    """Rows row + 3 a + i of lane l: scale P_i . g_a for the four nodes a."""
    k = row * LANES + l
    _put_node(buf, k, p, g[0, e], g[1, e], g[2, e], scale)
    _put_node(buf, k + 3 * LANES, p, g[3, e], g[4, e], g[5, e], scale)
    _put_node(buf, k + 6 * LANES, p, g[6, e], g[7, e], g[8, e], scale)
    _put_node(buf, k + 9 * LANES, p, g[9, e], g[10, e], g[11, e], scale)


@njit(cache=True, inline="always")
def _rows(buf, row, l):
    """Rows row to row + 8 of lane l (a 3 x 3 matrix, row by row)."""
    k = row * LANES + l
    return (
        buf[k],
        buf[k + LANES],
        buf[k + 2 * LANES],
        buf[k + 3 * LANES],
        buf[k + 4 * LANES],
        buf[k + 5 * LANES],
        buf[k + 6 * LANES],
        buf[k + 7 * LANES],
        buf[k + 8 * LANES],
    )


@njit(cache=True, inline="always")
def _put_rows(buf, row, l, a):
    """Rows row to row + 8 of lane l = the 3 x 3 matrix a (row by row)."""
    a00, a01, a02, a10, a11, a12, a20, a21, a22 = a
    k = row * LANES + l
    buf[k] = a00
    buf[k + LANES] = a01
    buf[k + 2 * LANES] = a02
    buf[k + 3 * LANES] = a10
    buf[k + 4 * LANES] = a11
    buf[k + 5 * LANES] = a12
    buf[k + 6 * LANES] = a20
    buf[k + 7 * LANES] = a21
    buf[k + 8 * LANES] = a22


@njit(cache=True, nogil=True, error_model="numpy")
def _blocks(
    lo, hi, x, v, nodes, g, vols, mu, lam, elem_forces, elem_kv, frames, dets, energies, last
):
    """Elements lo to hi - 1, `LANES` at a time. The loops over a block's elements have no
    branch (LLVM computes four elements per AVX2 register): deformation gradients and
    `POLAR_STEPS` Newton steps; more steps for the whole block while one of its (uninverted)
    elements moves by more than the tolerance; stresses, forces and energies; K_s v when `v`
    has rows. The block's results are then copied out, with the last polar step of each
    element (inf where det F <= 0)."""
    buf = numba.carray(_block_buffer(), (_ROWS * LANES,))
    with_v = v.shape[0] > 0
    for b in range(lo, hi, LANES):
        n = min(LANES, hi - b)
        for l in range(n):
            f = _gradient(x, nodes, g, b + l)
            f00, f01, f02, f10, f11, f12, f20, f21, f22 = f
            det = (
                f00 * (f11 * f22 - f12 * f21)
                - f01 * (f10 * f22 - f12 * f20)
                + f02 * (f10 * f21 - f11 * f20)
            )
            r, d = _newton_step(f)
            r, d = _newton_step(r)
            r, d = _newton_step(r)
            _put_rows(buf, _F, l, f)
            _put_rows(buf, _R, l, r)
            buf[_DET * LANES + l] = det
            buf[_LAST * LANES + l] = d if det > 0.0 else np.inf
        for _ in range(MAX_POLAR_STEPS - POLAR_STEPS):
            moving = False
            for l in range(n):
                d = buf[_LAST * LANES + l]
                moving |= d >= kernels._POLAR_TOL and d < np.inf
            if not moving:
                break
            for l in range(n):
                r, d = _newton_step(_rows(buf, _R, l))
                _put_rows(buf, _R, l, r)
                buf[_LAST * LANES + l] = d if buf[_DET * LANES + l] > 0.0 else np.inf
        for l in range(n):
            e = b + l
            f = _rows(buf, _F, l)
            r = _rows(buf, _R, l)
            sig, tr, eps2 = _isotropic(_transpose_times(r, f), mu[e], lam[e], 1.0)
            _put_nodal(buf, 0, l, _times(r, sig), g, e, -vols[e])
            buf[_ENERGY * LANES + l] = vols[e] * (mu[e] * eps2 + 0.5 * lam[e] * tr * tr)
        if with_v:
            for l in range(n):
                e = b + l
                r = _rows(buf, _R, l)
                ds, _, _ = _isotropic(
                    _transpose_times(r, _gradient(v, nodes, g, e)), mu[e], lam[e], 0.0
                )
                _put_nodal(buf, _KV, l, _times(r, ds), g, e, vols[e])
        for l in range(n):
            e = b + l
            for a in range(4):
                for i in range(3):
                    elem_forces[e, a, i] = buf[(3 * a + i) * LANES + l]
                    if with_v:
                        elem_kv[e, a, i] = buf[(_KV + 3 * a + i) * LANES + l]
            for k in range(9):
                frames[e, k // 3, k % 3] = buf[(_R + k) * LANES + l]
            dets[e] = buf[_DET * LANES + l]
            energies[e] = buf[_ENERGY * LANES + l]
            last[e] = buf[_LAST * LANES + l]


@njit(cache=True, parallel=True, nogil=True)
def corotational_forces(
    x, v, tets, grads, vols, mu, lam, nodes, g, elem_forces, elem_kv, frames, dets
):
    """:func:`pliant.fem.kernels.internal_forces` for the polar corotational law (tag 0), the
    elements taken `LANES` at a time (`nodes`, `g`: :func:`soa_layout` of `tets`, `grads`).
    Same outputs; returns the energy."""
    m = tets.shape[0]
    energies = np.empty(m)
    last = np.empty(m)
    bounds, n_chunks = kernels._chunks(m)
    for c in prange(n_chunks):
        lo, hi = bounds[c], bounds[c + 1]
        _blocks(
            lo,
            hi,
            x,
            v,
            nodes,
            g,
            vols,
            mu,
            lam,
            elem_forces,
            elem_kv,
            frames,
            dets,
            energies,
            last,
        )
        scratch = np.empty((7, 3, 3))
        for e in range(lo, hi):
            if not last[e] < kernels._POLAR_TOL:
                # The element again, one at a time (the polar law reads no edge frame: tets
                # and frames stand in for frame_nodes and rest_frames).
                energies[e] = kernels._element(
                    e,
                    x,
                    v,
                    tets,
                    grads,
                    vols,
                    mu,
                    lam,
                    0,
                    tets,
                    frames,
                    elem_forces,
                    elem_kv,
                    frames,
                    dets,
                    scratch,
                )
    return energies.sum()
