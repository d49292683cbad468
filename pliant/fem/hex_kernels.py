"""Compiled kernels of corotational trilinear hexahedra (SOFA's HexahedronFEMForceField).

Each element has a linear stiffness K0 (24 x 24, node-major) computed once at rest, and a
rotation R = Q(x) Q(X)^T from a frame Q of its averaged edge vectors e_j = sum_a xi_a,j x_a / 4
(xi_a the node's natural coordinates in {-1, 1}^3): SOFA's "large" method takes the
Gram-Schmidt frame of e_x and e_y, "polar" the polar rotation of [e_x e_y e_z]. The element
force is f = -R K0 (R^T x - X), its energy (K0 d) . d / 2 with d = R^T x - X, and the tangent
SOFA assembles R K0 R^T (the rotation held).
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from pliant.fem.kernels import _active, _chunks, _det3, _frame_of, _polar


@njit(cache=True, inline="always")
def _edge_matrix(x, nodes, corners, out):
    """out[:, j] = sum_a corners[a, j] x[nodes[a]] / 4 (the averaged edges along x, y, z)."""
    for i in range(3):
        for j in range(3):
            s = 0.0
            for a in range(8):
                s += corners[a, j] * x[nodes[a], i]
            out[i, j] = 0.25 * s


@njit(cache=True, inline="always")
def _frame(edges, tag, q, work):
    """q = the element's frame from its edge matrix: polar (tag 0) or Gram-Schmidt of the
    x and y edges (tags 2, 3)."""
    if tag == 0:
        _polar(edges, q, work)
    else:
        _frame_of(edges[0, 0], edges[1, 0], edges[2, 0], edges[0, 1], edges[1, 1], edges[2, 1], q)


@njit(cache=True)
def rest_frames(x, hexes, corners, tag):
    """Frames (m, 3, 3) and edge-matrix determinants (m,) of the elements at positions x."""
    m = hexes.shape[0]
    frames = np.empty((m, 3, 3))
    dets = np.empty(m)
    edges = np.empty((3, 3))
    work = np.empty((3, 3))
    for e in range(m):
        _edge_matrix(x, hexes[e], corners, edges)
        dets[e] = _det3(edges)
        _frame(edges, tag, frames[e], work)
    return frames, dets


@njit(cache=True, parallel=True, nogil=True)
def internal_forces(
    x,
    v,
    hexes,
    rest,
    k0,
    corners,
    tag,
    frames0,
    dets0,
    elem_forces,
    elem_kv,
    frames,
    dets,
):
    """Element forces -R K0 (R^T x - X) into `elem_forces` (m, 8, 3), rotations R into
    `frames`, det of the edge matrix relative to rest into `dets` (an element whose ratio is
    not positive gives no force, as a tetrahedron: see `kernels._active`) and, when `v`
    (n, 3) is not empty, R K0 R^T v into `elem_kv` (m, 8, 3). Returns the energy."""
    m = hexes.shape[0]
    with_v = v.shape[0] > 0
    bounds, n_chunks = _chunks(m)
    energies = np.zeros(n_chunks)
    for c in prange(n_chunks):
        edges = np.empty((3, 3))
        q = np.empty((3, 3))
        work = np.empty((3, 3))
        d = np.empty(24)
        kd = np.empty(24)
        energy = 0.0
        for e in range(bounds[c], bounds[c + 1]):
            nodes = hexes[e]
            _edge_matrix(x, nodes, corners, edges)
            det = _det3(edges) / dets0[e]
            dets[e] = det
            if not _active(det, tag):
                elem_forces[e] = 0.0
                frames[e] = 0.0
                if with_v:
                    elem_kv[e] = 0.0
                continue
            _frame(edges, tag, q, work)
            r = frames[e]
            q0 = frames0[e]
            for i in range(3):
                for j in range(3):
                    r[i, j] = q[i, 0] * q0[j, 0] + q[i, 1] * q0[j, 1] + q[i, 2] * q0[j, 2]
            for a in range(8):
                n = nodes[a]
                for i in range(3):
                    d[3 * a + i] = (
                        r[0, i] * x[n, 0] + r[1, i] * x[n, 1] + r[2, i] * x[n, 2] - rest[n, i]
                    )
            _rotated_product(k0[e], d, kd, r, elem_forces[e], -1.0)
            for k in range(24):
                energy += 0.5 * d[k] * kd[k]
            if with_v:
                for a in range(8):
                    n = nodes[a]
                    for i in range(3):
                        d[3 * a + i] = r[0, i] * v[n, 0] + r[1, i] * v[n, 1] + r[2, i] * v[n, 2]
                _rotated_product(k0[e], d, kd, r, elem_kv[e], 1.0)
        energies[c] = energy
    return energies.sum()


@njit(cache=True, inline="always")
def _rotated_product(k0, local, kd, r, out, sign):
    """kd = K0 local, then out[a] = sign R kd[a] (8 x 3)."""
    for row in range(24):
        s = 0.0
        for col in range(24):
            s += k0[row, col] * local[col]
        kd[row] = s
    for a in range(8):
        for i in range(3):
            out[a, i] = sign * (
                r[i, 0] * kd[3 * a] + r[i, 1] * kd[3 * a + 1] + r[i, 2] * kd[3 * a + 2]
            )


@njit(cache=True, parallel=True, nogil=True)
def stiffness_matvec(u, elem_dofs, k0, frames, dets, tag, elem_out):
    """Element contributions R K0 R^T u_e (m, 8, 3, k) of k free-DoF vectors u (n_free, k);
    elem_dofs (m, 24) maps element DoFs to free DoFs (-1 held). Gather with
    `kernels.gather_free`."""
    m = elem_dofs.shape[0]
    k = u.shape[1]
    bounds, n_chunks = _chunks(m)
    for c in prange(n_chunks):
        local = np.empty(24)
        kd = np.empty(24)
        out = np.empty((8, 3))
        ue = np.empty(3)
        for e in range(bounds[c], bounds[c + 1]):
            if not _active(dets[e], tag):
                elem_out[e] = 0.0
                continue
            r = frames[e]
            for col in range(k):
                for a in range(8):
                    for i in range(3):
                        dof = elem_dofs[e, 3 * a + i]
                        ue[i] = u[dof, col] if dof >= 0 else 0.0
                    for i in range(3):
                        local[3 * a + i] = r[0, i] * ue[0] + r[1, i] * ue[1] + r[2, i] * ue[2]
                _rotated_product(k0[e], local, kd, r, out, 1.0)
                for a in range(8):
                    for i in range(3):
                        elem_out[e, a, i, col] = out[a, i]


@njit(cache=True, nogil=True)
def assembly(k0, frames, dets, tag, scatter, data):
    """data[scatter[e, r, c]] += (R K0 R^T)[r, c], element by element."""
    rk = np.empty((24, 24))
    for e in range(k0.shape[0]):
        if not _active(dets[e], tag):
            continue
        r = frames[e]
        for row in range(24):  # rk = K0 R^T (blockwise)
            for b in range(8):
                for j in range(3):
                    rk[row, 3 * b + j] = (
                        k0[e, row, 3 * b] * r[j, 0]
                        + k0[e, row, 3 * b + 1] * r[j, 1]
                        + k0[e, row, 3 * b + 2] * r[j, 2]
                    )
        for a in range(8):
            for i in range(3):
                row = 3 * a + i
                for col in range(24):
                    pos = scatter[e, row, col]
                    if pos >= 0:
                        data[pos] += (
                            r[i, 0] * rk[3 * a, col]
                            + r[i, 1] * rk[3 * a + 1, col]
                            + r[i, 2] * rk[3 * a + 2, col]
                        )
