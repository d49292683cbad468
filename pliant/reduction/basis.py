"""Proper orthogonal decomposition of displacement snapshots (thesis §3.1.2; Goury and Duriez,
IEEE T-RO 34(6), 2018).

The snapshots are the displacements q_s - q0 of the free DoFs. Optionally the three rigid
translations, t_x = (1, 0, 0, 1, 0, 0, ...) / sqrt(N) and likewise along y and z, are projected
out of them and prepended to the basis: a walker's travel is then carried by three coordinates
exactly, and the deformation modes are not spent on it. A thin SVD S = U s V^T of what is left
gives the deformation modes; their number is the smallest i >= 1 whose tail energy
sqrt(sum_{j >= i} s_j^2 / sum_j s_j^2) is at most the tolerance (the ModelOrderReduction
plugin's criterion). The basis is orthonormal in the Euclidean product of the free DoFs.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass

import numpy as np

from pliant.errors import ReductionError


def mesh_fingerprint(body) -> str:
    """A digest of the body's mesh, held nodes and membranes: a basis or reduced model is
    only valid for the mesh it was computed on."""
    if any(assembly.membrane.spans_elements for assembly in body.membranes):
        raise ReductionError(
            "pliant.reduction reduces tetrahedra and membranes on their faces, not a shell of"
            " triangles (pliant.fem.shell, SOFA's TriangleFEMForceField) joined to the body"
        )
    digest = hashlib.sha256()
    for array in (body.rest_positions, body.tets, body.fixed_nodes):
        digest.update(np.ascontiguousarray(array).tobytes())
    for assembly in body.membranes:
        digest.update(np.ascontiguousarray(assembly.membrane.triangles).tobytes())
    return digest.hexdigest()[:16]


@dataclass(frozen=True)
class ReducedBasis:
    """q = q0 + Phi alpha.

    Attributes:
        rest: q0 (n, 3), the body's rest positions.
        modes: Phi as nodal fields (n, 3, r), zero on held nodes; orthonormal.
        n_translation: how many of the first modes are rigid translations (0 or 3).
        singular_values: the POD's singular values (all of them, for the energy plot).
        fingerprint: the mesh's (:func:`mesh_fingerprint`).
    """

    rest: np.ndarray
    modes: np.ndarray
    n_translation: int
    singular_values: np.ndarray
    fingerprint: str

    @property
    def n_modes(self) -> int:
        return int(self.modes.shape[2])

    def positions(self, coordinates: np.ndarray) -> np.ndarray:
        """q0 + Phi alpha, (n, 3)."""
        return self.rest + self.modes @ coordinates

    def coordinates(self, positions: np.ndarray) -> np.ndarray:
        """alpha = Phi^T (q - q0), the orthogonal projection's coordinates."""
        flat = self.modes.reshape(-1, self.n_modes)
        return flat.T @ (np.asarray(positions) - self.rest).reshape(-1)

    def truncated(self, n_modes: int) -> ReducedBasis:
        """The basis of its first `n_modes` modes."""
        if not 1 <= n_modes <= self.n_modes:
            raise ReductionError(f"n_modes must lie in [1, {self.n_modes}], got {n_modes}")
        return ReducedBasis(
            self.rest,
            np.ascontiguousarray(self.modes[:, :, :n_modes]),
            min(self.n_translation, n_modes),
            self.singular_values,
            self.fingerprint,
        )

    def check(self, body) -> None:
        """ReductionError unless the basis is one of `body`'s mesh."""
        if self.modes.ndim != 3 or self.modes.shape[:2] != (body.n_nodes, 3):
            raise ReductionError(
                f"the basis has modes of shape {self.modes.shape}, the body {body.n_nodes}"
                " nodes: expected (n_nodes, 3, r)"
            )
        if self.fingerprint != mesh_fingerprint(body):
            raise ReductionError(
                "the basis was computed for another mesh (fingerprint"
                f" {self.fingerprint} != {mesh_fingerprint(body)}): rebuild it for this model"
            )


def check_snapshots(displacements: np.ndarray, n_nodes: int) -> np.ndarray:
    """(s, n, 3) float snapshots, or ReductionError (wrong shape, non-finite values)."""
    d = np.asarray(displacements, dtype=float)
    if d.ndim != 3 or d.shape[1:] != (n_nodes, 3) or d.shape[0] == 0:
        raise ReductionError(
            f"snapshots must be (s >= 1, {n_nodes}, 3) positions or displacements, got {d.shape}"
        )
    bad = ~np.isfinite(d).all(axis=(1, 2))
    if bad.any():
        raise ReductionError(
            f"{int(bad.sum())} snapshot(s) hold NaN or inf (first: {int(np.argmax(bad))}):"
            " the full simulation diverged while they were recorded"
        )
    return d


def check_tolerance(name: str, value: float) -> float:
    v = float(value)
    if not (np.isfinite(v) and 0.0 < v < 1.0):
        raise ReductionError(f"{name} must lie in (0, 1), got {value!r}")
    return v


def translation_modes(body) -> np.ndarray:
    """(n, 3, 3) the unit rigid translations along x, y, z; ReductionError for a held body."""
    if body.fixed_nodes.size:
        raise ReductionError(
            "a body with held nodes cannot translate rigidly: build its basis without"
            " translation modes"
        )
    n = body.n_nodes
    modes = np.zeros((n, 3, 3))
    for axis in range(3):
        modes[:, axis, axis] = 1.0 / np.sqrt(n)
    return modes


def pod(
    body,
    positions: np.ndarray,
    *,
    tolerance: float = 1e-3,
    translation: bool | None = None,
    max_modes: int | None = None,
) -> ReducedBasis:
    """The POD basis of position snapshots (s, n, 3) of `body`.

    Args:
        tolerance: largest tail energy of the modes left out, in (0, 1).
        translation: prepend the rigid translations (projected out of the snapshots first);
            None: when the body has no held node.
        max_modes: at most this many deformation modes.
    """
    tolerance = check_tolerance("the POD tolerance", tolerance)
    q = check_snapshots(positions, body.n_nodes)
    if translation is None:
        translation = body.fixed_nodes.size == 0
    d = body.gather((q - body.rest_positions).transpose(1, 2, 0))  # (n_free, s)
    rigid = body.gather(translation_modes(body)) if translation else np.zeros((d.shape[0], 0))
    d = d - rigid @ (rigid.T @ d)
    u, s, _ = np.linalg.svd(d, full_matrices=False)
    energy = float(np.sum(s * s))
    if energy == 0.0:
        raise ReductionError("the snapshots hold no deformation (all at rest or rigid)")
    tail = np.sqrt(np.maximum(energy - np.concatenate([[0.0], np.cumsum(s * s)]), 0.0) / energy)
    keep = int(np.argmax(tail <= tolerance)) if np.any(tail <= tolerance) else s.size
    keep = max(1, keep if max_modes is None else min(keep, int(max_modes)))
    free = np.hstack([rigid, u[:, :keep]])
    return ReducedBasis(
        body.rest_positions.copy(),
        np.ascontiguousarray(body.scatter(free)),
        rigid.shape[1],
        s,
        mesh_fingerprint(body),
    )


def full_basis(body) -> ReducedBasis:
    """The identity on the free DoFs (every mode): the reduced step is then the full one."""
    return ReducedBasis(
        body.rest_positions.copy(),
        np.ascontiguousarray(body.scatter(np.eye(body.n_free))),
        0,
        np.zeros(0),
        mesh_fingerprint(body),
    )
