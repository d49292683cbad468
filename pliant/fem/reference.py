"""Plain NumPy transcription of the element kernels, for the tests (STYLE item 4).

Slow and obvious on purpose: one element at a time, SVD-based polar decomposition,
matrix products as written in the formulas.
"""

from __future__ import annotations

import numpy as np


def polar_rotation(f: np.ndarray) -> np.ndarray:
    """R of F = R S from the SVD F = U S V^T: R = U V^T (det F > 0)."""
    u, _, vt = np.linalg.svd(f)
    return u @ vt


def first_piola(f: np.ndarray, mu: float, lam: float, material: str) -> np.ndarray:
    if material == "corotational":
        r = polar_rotation(f)
        s = r.T @ f
        eps = 0.5 * (s + s.T) - np.eye(3)
        return r @ (2.0 * mu * eps + lam * np.trace(eps) * np.eye(3))
    j = np.linalg.det(f)
    fit = np.linalg.inv(f).T
    return mu * (f - fit) + lam * np.log(j) * fit


def energy_density(f: np.ndarray, mu: float, lam: float, material: str) -> float:
    if material == "corotational":
        r = polar_rotation(f)
        eps = 0.5 * (r.T @ f + f.T @ r) - np.eye(3)
        return float(mu * np.sum(eps * eps) + 0.5 * lam * np.trace(eps) ** 2)
    j = np.linalg.det(f)
    return float(0.5 * mu * (np.sum(f * f) - 3.0) - mu * np.log(j) + 0.5 * lam * np.log(j) ** 2)


def internal_forces(points, tets, rest, mu, lam, material):
    """Nodal internal forces f_a = -V P(F) g_a and the total energy."""
    forces = np.zeros_like(points)
    energy = 0.0
    for tet in tets:
        dm = (rest[tet[1:]] - rest[tet[0]]).T
        ds = (points[tet[1:]] - points[tet[0]]).T
        vol = np.linalg.det(dm) / 6.0
        f = ds @ np.linalg.inv(dm)
        grads = np.vstack([-np.linalg.inv(dm).sum(axis=0), np.linalg.inv(dm)])
        p = first_piola(f, mu, lam, material)
        forces[tet] -= vol * grads @ p.T
        energy += vol * energy_density(f, mu, lam, material)
    return forces, energy
