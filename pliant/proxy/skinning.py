"""Skinning of a FEM robot's surface onto a proxy's skeleton (thesis §4.1.1 step iii,
linear blend skinning [Dur+18]).

Each surface vertex v is carried by its nearest skeleton nodes j, rigidly with each node's
frame and blended: p(v) = sum_j w_j (x_j + R_j R0_j^T (v - x0_j)), weights w_j from the inverse
rest distances, summing to one. At rest every term is v, so the skinned surface is the FEM
surface; under a rigid motion of the skeleton every term moves by it, so the blend does.

A skinning is also a set of colliding points (``Contacts(points=skinning)``): the proxy then
touches the floor and the cube through the FEM robot's surface, not through balls at its
nodes. A point's rows follow from its first variation, with r_j = R_j R0_j^T (v - x0_j) its arm
from node j and omega_j that node's spin (world frame):

    dp = sum_j w_j (dx_j + omega_j x r_j),
    d . dp = sum_j w_j (d . dx_j + (r_j x d) . omega_j),

linearised at the step's start, as every contact row is.
"""

from __future__ import annotations

import numpy as np

from pliant.constraints.base import JacobianRows
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

    #: the points turn with the node frames: their rows depend on the state
    linear = False

    def __len__(self) -> int:
        return int(self.nodes.shape[0])

    def positions(self, positions: np.ndarray) -> np.ndarray:
        """(V, 3) the skinned surface at a proxy state's positions."""
        x = self.rod.centreline(positions)
        carried = x[self.nodes] + self._arms(positions)
        return np.einsum("vk,vki->vi", self.weights, carried)

    def _arms(self, positions: np.ndarray, index: np.ndarray | None = None) -> np.ndarray:
        """(V, k, 3) each vertex's arm r_j from each carrying node, in the world frame."""
        nodes = self.nodes if index is None else self.nodes[index]
        local = self.local if index is None else self.local[index]
        return np.einsum("vkij,vkj->vki", self.rod.frames(positions)[nodes], local)

    def displacement(self, positions: np.ndarray, increment: np.ndarray) -> np.ndarray:
        """(V, 3) the vertices' displacement under a rod increment (translations of the
        centreline, spins of the frames) from `positions`, to first order."""
        n = self.rod.n_centreline
        moved = increment[self.nodes] + np.cross(increment[n + self.nodes], self._arms(positions))
        return np.einsum("vk,vki->vi", self.weights, moved)

    def rows(
        self, positions: np.ndarray, index: np.ndarray, directions: np.ndarray
    ) -> JacobianRows:
        """Rows d . dp of the vertices `index`, r directions each (`directions` (k, r, 3)),
        over the rod's DoFs: the carrying nodes' translations, then their spins."""
        index = np.asarray(index, dtype=np.int64)
        nodes, w = self.nodes[index], self.weights[index]
        arms = self._arms(positions, index)  # (k, m, 3)
        k, m = nodes.shape
        r = directions.shape[1]
        translation = w[:, None, :, None] * directions[:, :, None, :]
        spin = w[:, None, :, None] * np.cross(arms[:, None, :, :], directions[:, :, None, :])
        columns = np.concatenate([nodes, self.rod.n_centreline + nodes], axis=1)
        return JacobianRows(
            np.repeat(columns[:, None, :], r, axis=1).reshape(k * r, 2 * m),
            np.concatenate([translation, spin], axis=2).reshape(k * r, 2 * m, 3),
        )
