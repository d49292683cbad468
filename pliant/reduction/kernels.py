"""Compiled kernels of the reduced step: cavity volumes and their gradients on the cavity
walls, for a few hundred triangles per step (NumPy's cross products cost more in overhead
than in arithmetic there). The plain definition they follow is
:class:`pliant.constraints.cavity.CavityActuator` (V = sum x0 . (x1 x x2) / 6 and its
gradient), which the tests compare them with."""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def cavity_volume(x, triangles):
    """V(x) = sum over the triangles of x0 . (x1 x x2) / 6."""
    v = 0.0
    for t in range(triangles.shape[0]):
        a, b, c = triangles[t, 0], triangles[t, 1], triangles[t, 2]
        v += (
            x[a, 0] * (x[b, 1] * x[c, 2] - x[b, 2] * x[c, 1])
            + x[a, 1] * (x[b, 2] * x[c, 0] - x[b, 0] * x[c, 2])
            + x[a, 2] * (x[b, 0] * x[c, 1] - x[b, 1] * x[c, 0])
        )
    return v / 6.0


@njit(cache=True)
def cavity_gradient(x, triangles, local, out):
    """out (k, 3): dV/dx summed on each of the wall's k nodes (`local`: the triangles'
    vertices numbered 0..k-1), from each triangle's (x1 x x2, x2 x x0, x0 x x1) / 6;
    returns V(x)."""
    out[:] = 0.0
    v = 0.0
    for t in range(triangles.shape[0]):
        for k in range(3):
            i, j = triangles[t, (k + 1) % 3], triangles[t, (k + 2) % 3]
            g0 = (x[i, 1] * x[j, 2] - x[i, 2] * x[j, 1]) / 6.0
            g1 = (x[i, 2] * x[j, 0] - x[i, 0] * x[j, 2]) / 6.0
            g2 = (x[i, 0] * x[j, 1] - x[i, 1] * x[j, 0]) / 6.0
            n = local[t, k]
            out[n, 0] += g0
            out[n, 1] += g1
            out[n, 2] += g2
            if k == 0:
                a = triangles[t, 0]
                v += x[a, 0] * g0 + x[a, 1] * g1 + x[a, 2] * g2
    return v


@njit(cache=True)
def membrane_forces_tangent(x, triangles, grads, areas, mu, lam, forces, tangents):
    """Forces (t, 9) and tangents (t, 9, 9) of membrane triangles, node-major (a, i), as
    :meth:`pliant.fem.membrane.Membrane.element_forces` and ``element_stiffness`` compute them
    (St Venant-Kirchhoff in plane stress, the geometric term with the tensile part of S);
    returns the energy."""
    energy = 0.0
    f = np.empty((3, 2))
    for t in range(triangles.shape[0]):
        g = grads[t]
        for i in range(3):
            for k in range(2):
                f[i, k] = (
                    x[triangles[t, 0], i] * g[0, k]
                    + x[triangles[t, 1], i] * g[1, k]
                    + x[triangles[t, 2], i] * g[2, k]
                )
        e00 = 0.5 * (f[0, 0] ** 2 + f[1, 0] ** 2 + f[2, 0] ** 2 - 1.0)
        e11 = 0.5 * (f[0, 1] ** 2 + f[1, 1] ** 2 + f[2, 1] ** 2 - 1.0)
        e01 = 0.5 * (f[0, 0] * f[0, 1] + f[1, 0] * f[1, 1] + f[2, 0] * f[2, 1])
        tr = e00 + e11
        s00 = 2.0 * mu * e00 + lam * tr
        s11 = 2.0 * mu * e11 + lam * tr
        s01 = 2.0 * mu * e01
        area = areas[t]
        energy += area * (mu * (e00 * e00 + e11 * e11 + 2.0 * e01 * e01) + 0.5 * lam * tr * tr)
        # Tensile part of S: its eigenvalues clipped at 0.
        mean = 0.5 * (s00 + s11)
        radius = np.sqrt(0.25 * (s00 - s11) ** 2 + s01 * s01)
        l1, l2 = mean + radius, mean - radius
        if l2 >= 0.0:
            p00, p11, p01 = s00, s11, s01
        elif l1 <= 0.0:
            p00, p11, p01 = 0.0, 0.0, 0.0
        else:  # only l1 > 0: l1 v v^T, v its unit eigenvector
            if abs(s01) > 1e-300:
                v0, v1 = s01, l1 - s00
            elif s00 >= s11:
                v0, v1 = 1.0, 0.0
            else:
                v0, v1 = 0.0, 1.0
            n = v0 * v0 + v1 * v1
            p00, p11, p01 = l1 * v0 * v0 / n, l1 * v1 * v1 / n, l1 * v0 * v1 / n
        for a in range(3):
            ga0, ga1 = g[a, 0], g[a, 1]
            # P g_a with P = F S.
            for i in range(3):
                fs0 = f[i, 0] * s00 + f[i, 1] * s01
                fs1 = f[i, 0] * s01 + f[i, 1] * s11
                forces[t, 3 * a + i] = -area * (fs0 * ga0 + fs1 * ga1)
            for b in range(3):
                gb0, gb1 = g[b, 0], g[b, 1]
                geometric = area * (ga0 * (p00 * gb0 + p01 * gb1) + ga1 * (p01 * gb0 + p11 * gb1))
                for i in range(3):
                    # F_i . (dS g_a) over j, dS_kl[b j] = mu (F_jk g_bl + F_jl g_bk)
                    # + lam (F_j . g_b) delta_kl.
                    for j in range(3):
                        fjg = f[j, 0] * gb0 + f[j, 1] * gb1
                        d00 = 2.0 * mu * f[j, 0] * gb0 + lam * fjg
                        d11 = 2.0 * mu * f[j, 1] * gb1 + lam * fjg
                        d01 = mu * (f[j, 0] * gb1 + f[j, 1] * gb0)
                        value = f[i, 0] * (d00 * ga0 + d01 * ga1) + f[i, 1] * (
                            d01 * ga0 + d11 * ga1
                        )
                        tangents[t, 3 * a + i, 3 * b + j] = area * value + (
                            geometric if i == j else 0.0
                        )
    return energy
