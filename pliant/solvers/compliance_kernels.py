"""Compiled kernels of :mod:`pliant.solvers.compliance`: the products of the points' rows P
(and of the contacts' frames F) with the kept columns Z = A^-1 P^T and with other columns.

A point's row block reads the free DoFs `dofs[i, n, a]` (node n of the point, axis a; -1 where
the node is held) with the weights `weights[i, n, a]` (0 where held). Written as loops over the
few (point, node, axis) triples: as NumPy expressions, their gathers and the einsums over
(k, 3, k, 3) blocks cost more than the products themselves (the reference, solving every
column, is :meth:`pliant.solvers.implicit_euler.ImplicitEuler._condense`, compared with these in
tests/contact/test_contact_fem.py).
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, inline="always")
def _point_value(values, dofs, weights, i, a, col):
    """(P_i values)_a in column `col`: sum_n weights[i, n, a] values[dofs[i, n, a], col] over
    the point's free DoFs."""
    total = 0.0
    for n in range(dofs.shape[1]):
        if dofs[i, n, a] >= 0:
            total += weights[i, n, a] * values[dofs[i, n, a], col]
    return total


@njit(cache=True)
def point_block(store, dofs, weights, slots):
    """(3k, 3k) P A^-1 P^T between k points: entry (3i + a, 3j + b) is
    sum_n weights[i, n, a] store[dofs[i, n, a], 3 slots[j] + b]."""
    k = dofs.shape[0]
    out = np.zeros((3 * k, 3 * k))
    for j in range(k):
        for b in range(3):
            column = 3 * slots[j] + b
            for i in range(k):
                for a in range(3):
                    out[3 * i + a, 3 * j + b] = _point_value(store, dofs, weights, i, a, column)
    return out


@njit(cache=True)
def framed_block(frames, block):
    """F B F^T for the block diagonal F of the frames (k, 3, 3) and B (3k, 3k)."""
    k = frames.shape[0]
    out = np.empty((3 * k, 3 * k))
    half = np.empty((3, 3))  # F_i B_ij
    for i in range(k):
        for j in range(k):
            for r in range(3):
                for b in range(3):
                    half[r, b] = (
                        frames[i, r, 0] * block[3 * i, 3 * j + b]
                        + frames[i, r, 1] * block[3 * i + 1, 3 * j + b]
                        + frames[i, r, 2] * block[3 * i + 2, 3 * j + b]
                    )
            for r in range(3):
                for s in range(3):
                    out[3 * i + r, 3 * j + s] = (
                        half[r, 0] * frames[j, s, 0]
                        + half[r, 1] * frames[j, s, 1]
                        + half[r, 2] * frames[j, s, 2]
                    )
    return out


@njit(cache=True)
def framed_rows(frames, dofs, weights, values):
    """(3k, c) F P values: row 3i + r is sum_a frames[i, r, a] (P_i values)_a, for free-DoF
    values (n_free, c)."""
    k, c = dofs.shape[0], values.shape[1]
    out = np.zeros((3 * k, c))
    point = np.empty(3)
    for i in range(k):
        for col in range(c):
            for a in range(3):
                point[a] = _point_value(values, dofs, weights, i, a, col)
            for r in range(3):
                out[3 * i + r, col] = (
                    frames[i, r, 0] * point[0]
                    + frames[i, r, 1] * point[1]
                    + frames[i, r, 2] * point[2]
                )
    return out
