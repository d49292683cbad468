"""Compiled kernel of the rigid bodies' contact rows: each contact frame's rows on the twist of
the body carrying the contact point (fem.rigid.contact_twist_jacobian is its definition)."""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def contact_twist_rows(frames, points, bodies, centres, n):
    """(3k, 6n) rows f . J(p) = (f, a x f) of each contact's frame rows f on the twist of the
    body carrying its point (a = p - x the arm; zero rows for bodies outside [0, n)):
    fem.rigid.contact_twist_jacobian, compiled."""
    k = points.shape[0]
    jac = np.zeros((3 * k, 6 * n))
    for c in range(k):
        i = bodies[c]
        if i < 0 or i >= n:
            continue
        a0, a1, a2 = (
            points[c, 0] - centres[i, 0],
            points[c, 1] - centres[i, 1],
            points[c, 2] - centres[i, 2],
        )
        for r in range(3):
            f0, f1, f2 = frames[c, r, 0], frames[c, r, 1], frames[c, r, 2]
            row = jac[3 * c + r, 6 * i : 6 * i + 6]
            row[0], row[1], row[2] = f0, f1, f2
            row[3], row[4], row[5] = a1 * f2 - a2 * f1, a2 * f0 - a0 * f2, a0 * f1 - a1 * f0
    return jac
