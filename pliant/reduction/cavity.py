"""A cavity's row in the reduced step: its volume change and gradient in reduced coordinates,
from its walls or as an exact cubic polynomial of the coordinates.

The volume enclosed by a cavity's walls is a sum of triple products over their triangles,

    V(q) = 1/6 sum_t x_a . (x_b x x_c),

trilinear in the three vertices. With x = x0 + Phi alpha on every node it is therefore a cubic
polynomial of alpha, whose coefficients are sums over the walls computed once:

    6 (V(alpha) - V(0)) = l . alpha + alpha^T Q alpha + C(alpha, alpha, alpha),

    l_i    = sum_t  A_i . (b x c) + B_i . (c x a) + C_i . (a x b),
    Q_jk   = sum_t  a . (B_j x C_k) + b . (C_j x A_k) + c . (A_j x B_k),
    C_ijk  = sum_t  A_i . (B_j x C_k),

a, b, c the triangle's rest vertices and A, B, C (3, r) the basis on them. With Q and C
symmetrised, dV/dalpha = (l + 2 Q alpha + 3 C(alpha, alpha, .)) / 6. A step then evaluates the
cavity's row in O(r^3) operations, whatever the size of its walls, and the walls' nodes need no
positions at all (on the reference Multigait the five cavities' walls hold 7400 nodes the
reduced step would otherwise place at every step). The price is r^3 coefficients per cavity
(2.9 MB at 71 modes) and r^3 operations a call: small walls under many modes are cheaper
read from the walls (:class:`WallCavity`, compiled kernels), and :func:`reduced_cavity`
chooses by that count.
"""

from __future__ import annotations

import itertools

import numpy as np

from pliant.constraints.cavity import CavityActuator
from pliant.reduction import kernels

#: Triangles per block when summing the cubic coefficients (bounds the work array).
_BLOCK_ENTRIES = 4_000_000


def reduced_cavity(
    cavity: CavityActuator, rest_positions: np.ndarray, modes: np.ndarray
) -> CavityPolynomial | WallCavity:
    """The cheaper evaluation of the cavity's row: the polynomial costs about 2 r^3 operations
    a call, the walls about 6 r per wall node (placing them and reading the gradient)."""
    r = modes.shape[2]
    wall_nodes = np.unique(cavity.triangles).size
    if r * r <= 3 * wall_nodes:
        return CavityPolynomial(cavity.triangles, rest_positions, modes)
    return WallCavity(cavity.triangles, rest_positions, modes)


class WallCavity:
    """A cavity's volume and gradient from its walls at the placed positions x (compiled
    kernels), the gradient read through the basis: dV/dalpha = dV/dq Phi."""

    def __init__(self, triangles: np.ndarray, rest_positions: np.ndarray, modes: np.ndarray):
        self.triangles = np.ascontiguousarray(triangles, dtype=np.int64)
        self.nodes, local = np.unique(self.triangles, return_inverse=True)
        self.local = np.ascontiguousarray(local.reshape(self.triangles.shape))
        self.rest_volume = kernels.cavity_volume(rest_positions, self.triangles)
        self._gradient = np.empty((self.nodes.size, 3))
        self._phi = np.ascontiguousarray(modes[self.nodes].reshape(-1, modes.shape[2]))

    def change(self, coordinates: np.ndarray, x: np.ndarray) -> float:
        """V - V(0), x: positions placed at q0 + Phi alpha on (at least) `nodes`."""
        return kernels.cavity_volume(x, self.triangles) - self.rest_volume

    def change_and_gradient(
        self, coordinates: np.ndarray, x: np.ndarray
    ) -> tuple[float, np.ndarray]:
        volume = kernels.cavity_gradient(x, self.triangles, self.local, self._gradient)
        return volume - self.rest_volume, self._gradient.reshape(-1) @ self._phi


class CavityPolynomial:
    """The exact cubic volume polynomial of one cavity on a reduced basis.

    Args:
        triangles: the walls (t, 3), oriented as the full cavity's.
        rest_positions: x0 (n, 3).
        modes: the basis Phi (n, 3, r).
    """

    def __init__(self, triangles: np.ndarray, rest_positions: np.ndarray, modes: np.ndarray):
        triangles = np.asarray(triangles, dtype=np.int64)
        r = modes.shape[2]
        x0 = [rest_positions[triangles[:, k]] for k in range(3)]  # (t, 3) each
        phi = [modes[triangles[:, k]] for k in range(3)]  # (t, 3, r) each
        self.n_modes = r
        self.nodes = np.zeros(0, dtype=np.int64)  # no positions needed
        self.rest_volume = float(np.einsum("tp,tp->", x0[0], np.cross(x0[1], x0[2])) / 6.0)
        self.linear = sum(
            np.einsum("tpi,tp->i", phi[k], np.cross(x0[(k + 1) % 3], x0[(k + 2) % 3]))
            for k in range(3)
        )
        # u . (X_j x Y_k) = -X_j . (u x Y_k): one product of (3t, r) matrices per term.
        quadratic = np.zeros((r, r))
        for k in range(3):
            u, x, y = x0[k], phi[(k + 1) % 3], phi[(k + 2) % 3]
            quadratic -= x.reshape(-1, r).T @ _cross_columns(u, y).reshape(-1, r)
        self.quadratic = 0.5 * (quadratic + quadratic.T)
        cubic = np.zeros((r, r * r))
        block = max(1, _BLOCK_ENTRIES // (3 * r * r))
        for s in range(0, len(triangles), block):
            a, b, c = (p[s : s + block] for p in phi)
            # (B_j x C_k) for every pair of modes: (t, 3, r, r).
            pairs = np.stack(
                [
                    b[:, 1, :, None] * c[:, 2, None, :] - b[:, 2, :, None] * c[:, 1, None, :],
                    b[:, 2, :, None] * c[:, 0, None, :] - b[:, 0, :, None] * c[:, 2, None, :],
                    b[:, 0, :, None] * c[:, 1, None, :] - b[:, 1, :, None] * c[:, 0, None, :],
                ],
                axis=1,
            )
            cubic += a.reshape(-1, r).T @ pairs.reshape(-1, r * r)
        cubic = cubic.reshape(r, r, r)
        # Only the symmetric part enters C(alpha, alpha, alpha).
        self.cubic = sum(cubic.transpose(p) for p in itertools.permutations(range(3))) / 6.0
        self._cubic_flat = self.cubic.reshape(r, r * r)
        self._last: tuple[np.ndarray, float, np.ndarray] | None = None

    def change(self, coordinates: np.ndarray, x: np.ndarray | None = None) -> float:
        """V(alpha) - V(0) (x, the positions, is not needed)."""
        return self.change_and_gradient(coordinates)[0]

    def change_and_gradient(
        self, coordinates: np.ndarray, x: np.ndarray | None = None
    ) -> tuple[float, np.ndarray]:
        """V(alpha) - V(0) and dV/dalpha (r,). The last evaluation is kept: a step asks for
        the volume at its end, and the next step for its row at the same coordinates."""
        a = coordinates
        if self._last is not None and np.array_equal(a, self._last[0]):
            return self._last[1], self._last[2].copy()
        ca = self._cubic_flat @ np.outer(a, a).reshape(-1)  # C(alpha, alpha, .)
        qa = self.quadratic @ a
        change = float((self.linear @ a + a @ qa + ca @ a) / 6.0)
        gradient = (self.linear + 2.0 * qa + 3.0 * ca) / 6.0
        self._last = (np.array(a, dtype=float), change, gradient)
        return change, gradient.copy()


def _cross_columns(u: np.ndarray, y: np.ndarray) -> np.ndarray:
    """u_t x Y_t[:, k] for every triangle t and column k: (t, 3) x (t, 3, r) -> (t, 3, r)."""
    return np.stack(
        [
            u[:, 1, None] * y[:, 2] - u[:, 2, None] * y[:, 1],
            u[:, 2, None] * y[:, 0] - u[:, 0, None] * y[:, 2],
            u[:, 0, None] * y[:, 1] - u[:, 1, None] * y[:, 0],
        ],
        axis=1,
    )
