"""Skinning of a FEM robot's surface onto a proxy's skeleton (thesis §4.1.1 step iii,
linear blend skinning [Dur+18]).

Each surface vertex v is carried by its nearest skeleton nodes j, rigidly with each node's
frame and blended: p(v) = sum_j w_j (x_j + R_j R0_j^T (v - x0_j)), weights w_j from the inverse
rest distances, summing to one. At rest every term is v, so the skinned surface is the FEM
surface; under a rigid motion of the skeleton every term moves by it, so the blend does.
"""

from __future__ import annotations

import numpy as np

from pliant.errors import ModelError
from pliant.fem.rod import RodBody


class Skinning:
    """Surface points carried by a rod skeleton's node frames.

    Args:
        rod: the skeleton (its rest centreline and rest frames).
        surface: (V, 3) the FEM robot's surface vertices at rest.
        neighbours: how many nearest nodes carry a vertex (1: rigid, per node).
    """

    def __init__(self, rod: RodBody, surface: np.ndarray, *, neighbours: int = 2) -> None:
        v = np.asarray(surface, dtype=float)
        if v.ndim != 2 or v.shape[1] != 3 or not np.all(np.isfinite(v)):
            raise ModelError(f"a skinned surface needs (V, 3) finite points, got {v.shape}")
        n = rod.n_centreline
        if not 1 <= neighbours <= n:
            raise ModelError(f"neighbours must lie in [1, {n}], got {neighbours}")
        self.rod = rod
        rest = rod.rest_positions
        x0, r0 = rod.centreline(rest), rod.frames(rest)
        distance = np.linalg.norm(v[:, None, :] - x0[None, :, :], axis=2)
        self.nodes = np.argsort(distance, axis=1)[:, :neighbours]
        near = np.take_along_axis(distance, self.nodes, axis=1)
        inverse = 1.0 / np.maximum(near, 1e-9 * (1.0 + near.max()))
        self.weights = inverse / inverse.sum(axis=1, keepdims=True)
        # The vertex in each carrying node's rest frame.
        self.local = np.einsum("vkji,vkj->vki", r0[self.nodes], v[:, None, :] - x0[self.nodes])

    def __len__(self) -> int:
        return int(self.nodes.shape[0])

    def positions(self, positions: np.ndarray) -> np.ndarray:
        """(V, 3) the skinned surface at a proxy state's positions."""
        x, r = self.rod.centreline(positions), self.rod.frames(positions)
        carried = x[self.nodes] + np.einsum("vkij,vkj->vki", r[self.nodes], self.local)
        return np.einsum("vk,vki->vi", self.weights, carried)
