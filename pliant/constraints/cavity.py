"""Pneumatic cavity actuator (SoftRobots' SurfacePressureConstraint)."""

from __future__ import annotations

import numpy as np

from pliant.constraints.base import Actuator, EmbeddedPoints, JacobianRows
from pliant.errors import ConstraintError

# Ordered vertex pairs (a, b) of a triangle, its third vertex c and the sign s of
# d^2 V / dx_a dx_b = s [x_c]_x / 6, for V = x0 . (x1 x x2) / 6: the derivative of
# dV/dx0 = x1 x x2 / 6 along x1 is -[x2]_x / 6, and likewise round the triangle.
_PAIR_A = np.array([0, 1, 2, 1, 2, 0])
_PAIR_B = np.array([1, 2, 0, 0, 1, 2])
_PAIR_C = np.array([2, 0, 1, 2, 0, 1])
_PAIR_SIGN = np.array([-1.0, -1.0, -1.0, 1.0, 1.0, 1.0])


def _skew(v: np.ndarray) -> np.ndarray:
    """[v]_x, the cross-product matrices of vectors (..., 3) -> (..., 3, 3)."""
    out = np.zeros((*v.shape, 3))
    out[..., 0, 1], out[..., 0, 2] = -v[..., 2], v[..., 1]
    out[..., 1, 0], out[..., 1, 2] = v[..., 2], -v[..., 0]
    out[..., 2, 0], out[..., 2, 1] = -v[..., 1], v[..., 0]
    return out


def enclosed_volume(x: np.ndarray, triangles: np.ndarray) -> float:
    """Volume enclosed by a closed triangulated surface: sum x0 . (x1 x x2) / 6 (Gauss)."""
    p = x[triangles]
    return float(np.einsum("ij,ij->i", p[:, 0], np.cross(p[:, 1], p[:, 2])).sum() / 6.0)


class CavityActuator(Actuator):
    """A closed cavity of the body, inflated by a pressure.

    delta = V(x) - V0, the volume growth; lambda is the pressure; H = dV/dx, so H^T lambda is
    the pressure force on the cavity walls (lambda times the area-weighted normals).

    Args:
        triangles: (t, 3) node indices of the cavity wall, a closed surface whose enclosed
            volume is positive (flip_normals=True reverses a surface given the other way).
        rest_positions: to define V0.
        points: the wall's vertices as points carried by the body (a surface mesh of its own
            mapped into the body, as SoftRobots' SurfacePressureConstraint under a
            BarycentricMapping); `triangles` then index these points instead of the nodes.
    """

    def __init__(
        self,
        triangles: np.ndarray,
        rest_positions: np.ndarray,
        *,
        flip_normals: bool = False,
        points: EmbeddedPoints | None = None,
        name: str = "cavity",
        **bounds,
    ) -> None:
        bounds.setdefault("min_force", 0.0)
        super().__init__(name=name, **bounds)
        tri = np.asarray(triangles, dtype=np.int64)
        if tri.ndim != 2 or tri.shape[1] != 3 or tri.shape[0] < 4:
            raise ConstraintError(
                f"{name}: a cavity needs a closed surface of at least 4 triangles"
            )
        self.points = points
        n_vertices = rest_positions.shape[0] if points is None else len(points)
        if tri.min() < 0 or tri.max() >= n_vertices:
            raise ConstraintError(f"{name}: cavity triangles index vertices that do not exist")
        self.triangles = tri[:, ::-1].copy() if flip_normals else tri
        edges = np.sort(
            np.concatenate(
                [self.triangles[:, [0, 1]], self.triangles[:, [1, 2]], self.triangles[:, [2, 0]]]
            ),
            axis=1,
        )
        _, counts = np.unique(edges, axis=0, return_counts=True)
        if np.any(counts != 2):
            raise ConstraintError(
                f"{name}: the cavity surface is not closed"
                f" ({np.count_nonzero(counts != 2)} open edges)"
            )
        self.rest_volume = self.volume(rest_positions)
        if not self.rest_volume > 0:
            raise ConstraintError(
                f"{name}: the cavity encloses a non-positive volume ({self.rest_volume:.3g});"
                " its normals are inverted: pass flip_normals=True"
            )
        self._nodes = (
            self.triangles.reshape(1, -1) if points is None else points.nodes.reshape(1, -1)
        )

    def _vertices(self, x: np.ndarray) -> np.ndarray:
        return x if self.points is None else self.points.positions(x)

    def volume(self, x: np.ndarray) -> float:
        return enclosed_volume(self._vertices(x), self.triangles)

    def distance(self, x: np.ndarray) -> np.ndarray:
        return np.array([self.volume(x) - self.rest_volume])

    def jacobian(self, x: np.ndarray) -> JacobianRows:
        p = self._vertices(x)[self.triangles]
        grad = (
            np.stack(
                [
                    np.cross(p[:, 1], p[:, 2]),
                    np.cross(p[:, 2], p[:, 0]),
                    np.cross(p[:, 0], p[:, 1]),
                ],
                axis=1,
            )
            / 6.0
        )
        if self.points is None:
            return JacobianRows(self._nodes, grad.reshape(1, -1, 3))
        # dV/dp per vertex, spread on each vertex's element nodes by its weights.
        per_vertex = np.zeros((len(self.points), 3))
        np.add.at(per_vertex, self.triangles, grad)
        values = per_vertex[:, None, :] * self.points.weights[:, :, None]
        return JacobianRows(self._nodes, values.reshape(1, -1, 3))

    def load_stiffness_pairs(self) -> tuple[np.ndarray, np.ndarray]:
        """Node pairs of :meth:`load_stiffness`, block for block: the ordered pairs of each
        triangle's vertices (of the nodes carrying them, for embedded points)."""
        a, b = self.triangles[:, _PAIR_A], self.triangles[:, _PAIR_B]
        if self.points is None:
            return a.ravel(), b.ravel()
        na, nb = self.points.nodes[a], self.points.nodes[b]  # (t, 6, 4)
        na, nb = np.broadcast_arrays(na[..., :, None], nb[..., None, :])
        return na.ravel(), nb.ravel()

    def load_stiffness(self, x: np.ndarray, pressure: float) -> np.ndarray:
        """(E, 3, 3) -d(H^T lambda)/dx = -lambda d^2 V/dx^2: the pressure's follower load
        turning and stretching with the walls (the diagonal blocks vanish, V being linear in
        each vertex). With it, the static solver's consistent tangent is the Hessian of the
        whole potential, and W = H K^-1 H^T the compliance under pressure control."""
        p = self._vertices(x)[self.triangles]  # (t, 3, 3)
        blocks = (-pressure / 6.0) * _PAIR_SIGN[None, :, None, None] * _skew(p[:, _PAIR_C])
        if self.points is None:
            return blocks.reshape(-1, 3, 3)
        w = self.points.weights
        wa, wb = w[self.triangles[:, _PAIR_A]], w[self.triangles[:, _PAIR_B]]  # (t, 6, 4)
        scale = wa[..., :, None] * wb[..., None, :]  # (t, 6, 4, 4)
        return (scale[..., None, None] * blocks[:, :, None, None]).reshape(-1, 3, 3)
