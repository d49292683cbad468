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


def edge_frame(corners: np.ndarray) -> np.ndarray:
    """SOFA's "large" frame of a tetrahedron's corners (4, 3): columns e_0 along the first
    edge, e_2 normal to the plane of the first three corners, e_1 = e_2 x e_0."""
    e0 = corners[1] - corners[0]
    e2 = np.cross(e0, corners[2] - corners[0])
    e0, e2 = e0 / np.linalg.norm(e0), e2 / np.linalg.norm(e2)
    return np.column_stack([e0, np.cross(e2, e0), e2])


def first_piola(
    f: np.ndarray, mu: float, lam: float, material: str, rotation: np.ndarray | None = None
) -> np.ndarray:
    """P(F); the corotational law uses `rotation` when given (else the polar one)."""
    if material == "corotational":
        r = polar_rotation(f) if rotation is None else rotation
        s = r.T @ f
        eps = 0.5 * (s + s.T) - np.eye(3)
        return r @ (2.0 * mu * eps + lam * np.trace(eps) * np.eye(3))
    j = np.linalg.det(f)
    fit = np.linalg.inv(f).T
    return mu * (f - fit) + lam * np.log(j) * fit


def energy_density(
    f: np.ndarray, mu: float, lam: float, material: str, rotation: np.ndarray | None = None
) -> float:
    if material == "corotational":
        r = polar_rotation(f) if rotation is None else rotation
        eps = 0.5 * (r.T @ f + f.T @ r) - np.eye(3)
        return float(mu * np.sum(eps * eps) + 0.5 * lam * np.trace(eps) ** 2)
    j = np.linalg.det(f)
    return float(0.5 * mu * (np.sum(f * f) - 3.0) - mu * np.log(j) + 0.5 * lam * np.log(j) ** 2)


def internal_forces(points, tets, rest, mu, lam, material, rotation="polar"):
    """Nodal internal forces f_a = -V P(F) g_a and the total energy; the corotational
    `rotation` is "polar" or "large" (R = Q(x) Q(X)^T from the edge frames)."""
    forces = np.zeros_like(points)
    energy = 0.0
    for tet in tets:
        dm = (rest[tet[1:]] - rest[tet[0]]).T
        ds = (points[tet[1:]] - points[tet[0]]).T
        vol = abs(np.linalg.det(dm)) / 6.0  # either orientation, as SOFA takes them
        f = ds @ np.linalg.inv(dm)
        grads = np.vstack([-np.linalg.inv(dm).sum(axis=0), np.linalg.inv(dm)])
        r = None
        if rotation == "large":
            r = edge_frame(points[tet]) @ edge_frame(rest[tet]).T
        p = first_piola(f, mu, lam, material, r)
        forces[tet] -= vol * grads @ p.T
        energy += vol * energy_density(f, mu, lam, material, r)
    return forces, energy
