"""Inertia tensors of solid shapes of uniform density, about their centre (the frame origin of
a rigid body carrying the shape, pliant.fem.rigid.RigidBody)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pliant.errors import ModelError
from pliant.geometry.collision import BoxUnion


def sphere_inertia(mass: float, radius: float) -> np.ndarray:
    """Solid sphere about its centre: 2/5 m r^2 I."""
    return 0.4 * mass * radius**2 * np.eye(3)


def box_inertia(mass: float, half_extents) -> np.ndarray:
    """Solid box about its centre, half extents (a, b, c): m/3 diag(b^2+c^2, a^2+c^2, a^2+b^2)."""
    a2, b2, c2 = np.asarray(half_extents, dtype=float) ** 2
    return mass / 3.0 * np.diag([b2 + c2, a2 + c2, a2 + b2])


def cylinder_inertia(mass: float, radius: float, half_length: float, axis: int = 2) -> np.ndarray:
    """Solid cylinder about its centre: m r^2 / 2 about its axis, m (3 r^2 + (2L)^2) / 12 across."""
    across = mass * (3.0 * radius**2 + 4.0 * half_length**2) / 12.0
    inertia = np.full(3, across)
    inertia[axis] = 0.5 * mass * radius**2
    return np.diag(inertia)


def capsule_inertia(mass: float, radius: float, half_length: float) -> np.ndarray:
    """Solid capsule along z (cylinder of height H = 2L capped by hemispheres), uniform density:
    with m_c, m_h the masses of the cylinder and of one hemisphere,
    I_z = m_c r^2 / 2 + 4/5 m_h r^2 and, across, m_c (H^2/12 + r^2/4)
    + 2 m_h (2/5 r^2 + H^2/4 + 3 H r / 8) (each hemisphere moved from its centroid, 3r/8
    from its flat face, to the capsule's centre)."""
    height = 2.0 * half_length
    cylinder, hemisphere = np.pi * radius**2 * height, 2.0 / 3.0 * np.pi * radius**3
    scale = mass / (cylinder + 2.0 * hemisphere)
    m_c, m_h = scale * cylinder, scale * hemisphere
    axial = 0.5 * m_c * radius**2 + 0.8 * m_h * radius**2
    across = m_c * (height**2 / 12.0 + radius**2 / 4.0) + 2.0 * m_h * (
        0.4 * radius**2 + height**2 / 4.0 + 3.0 * height * radius / 8.0
    )
    return np.diag([across, across, axial])


def box_union_inertia(mass: float, union: BoxUnion) -> np.ndarray:
    """Solid union of non-overlapping boxes, uniform density, about the union's frame origin:
    each box's inertia turned into that frame, R_j I_j R_j^T, and moved from its centre d_j
    by the parallel-axis theorem, + m_j (|d_j|^2 I - d_j d_j^T), with m_j its share of the
    volume."""
    volumes = np.array([np.prod(b.half_extents) for b in union.boxes])
    total = np.zeros((3, 3))
    for box, volume in zip(union.boxes, volumes, strict=True):
        m, d = mass * volume / volumes.sum(), box.position
        turned = box.rotation @ box_inertia(m, box.half_extents) @ box.rotation.T
        total += turned + m * (d @ d * np.eye(3) - np.outer(d, d))
    return total


@dataclass(frozen=True)
class MeshMass:
    """Mass properties of the solid a closed, outward-oriented triangle mesh bounds, uniform
    density: its volume, mass, centre of mass and inertia tensor about the centre of mass
    (axes of the mesh's frame)."""

    volume: float
    mass: float
    centre: np.ndarray
    inertia: np.ndarray


def mesh_mass(vertices, faces, density: float = 1.0) -> MeshMass:
    """Mass properties of the solid a closed triangle mesh (outward faces) bounds, by the
    divergence theorem: the solid is the signed sum of the tetrahedra (0, a, b, c) of its
    faces. A tetrahedron whose edge matrix is A = [a b c] has volume det(A)/6, first moment
    det(A)/6 (a + b + c)/4 and second moment int x x^T dV = det(A) A C A^T with
    C = (1 + delta_ij)/120 (Tonon, J. Math. Stat. 1(1), 2004); the inertia about the origin
    is tr(S) I - S, moved to the centre of mass by the parallel-axis theorem. Exact for the
    polyhedron (a sphere's tessellation gives the inscribed polyhedron's values)."""
    v = np.asarray(vertices, dtype=float)
    f = np.asarray(faces, dtype=np.int64)
    if v.ndim != 2 or v.shape[1] != 3 or f.ndim != 2 or f.shape[1] != 3 or len(f) < 4:
        raise ModelError(
            f"a closed mesh needs (n, 3) vertices and (m >= 4, 3) faces, got {v.shape} and"
            f" {f.shape}"
        )
    if not (np.isfinite(density) and density > 0.0):
        raise ModelError(f"the density must be finite and > 0, got {density!r}")
    edges = v[f]  # (m, 3 corners, 3 coordinates): the rows of A^T
    det = np.linalg.det(edges)
    volume = float(det.sum()) / 6.0
    if not volume > 0.0:
        raise ModelError(
            f"the mesh encloses a volume of {volume:.6g} <= 0: its faces are oriented inwards"
            " (or it is open or flat)"
        )
    centre = np.einsum("k,ki->i", det, edges.sum(axis=1)) / 24.0 / volume
    canonical = (np.ones((3, 3)) + np.eye(3)) / 120.0
    second = np.einsum("k,kai,ab,kbj->ij", det, edges, canonical, edges)
    second = density * (second - volume * np.outer(centre, centre))  # about the centre
    inertia = np.trace(second) * np.eye(3) - second
    return MeshMass(volume, density * volume, centre, 0.5 * (inertia + inertia.T))
