"""Rotation actuator: a torque or an angle on a rod node's orientation about a fixed axis.

A rod (:class:`pliant.fem.rod.RodBody`) carries its orientations as nodes of the body (rotation
vectors, varied by spatial spins). With R0 the node's rest orientation and a the unit axis,

    delta = a . log(R R0^T),    H = a^T J_l(log(R R0^T))^-1   (on the orientation node),

the turn about a from rest (exact for turns about a of less than pi). In force mode lambda is a
torque about a (for motion about a, J_l^-T a = a: the torque is exactly lambda a), as a motor on
the node's shaft; in displacement mode delta is the angle, as a servo. SPEC §2 lists the
servo/joint among the actuators.
"""

from __future__ import annotations

import numpy as np

from pliant.constraints.base import Actuator, JacobianRows
from pliant.errors import ConstraintError
from pliant.fem import rod_kernels


class RotationActuator(Actuator):
    """Turn of a rod node about a world axis, driven in torque (force mode) or angle.

    Args:
        rod: the rod body.
        node: centreline node whose orientation is turned.
        axis: the world axis (any non-zero length).
        Other keywords: see :class:`pliant.constraints.base.Actuator` (a torque may have
        either sign: min_force defaults to -inf here).
    """

    def __init__(self, rod, node: int, axis, *, name: str = "joint", **bounds) -> None:
        bounds.setdefault("min_force", -np.inf)
        super().__init__(name=name, **bounds)
        n = rod.n_centreline
        if not 0 <= int(node) < n:
            raise ConstraintError(f"{name}: node {node} is not a centreline node (0..{n - 1})")
        a = np.asarray(axis, dtype=float).reshape(3)
        norm = float(np.linalg.norm(a))
        if not (np.isfinite(norm) and norm > 0):
            raise ConstraintError(f"{name}: the axis must be finite and non-zero, got {axis!r}")
        self.axis = a / norm
        self.node = int(node) + n  # the orientation's row in the body
        rest = np.empty((3, 3))
        rod_kernels.so3_exp(np.ascontiguousarray(rod.rest_positions[self.node]), rest)
        self._rest_t = rest.T

    def _turn(self, x: np.ndarray) -> np.ndarray:
        r = np.empty((3, 3))
        rod_kernels.so3_exp(np.ascontiguousarray(x[self.node], dtype=float), r)
        phi = np.empty(3)
        rod_kernels.so3_log(r @ self._rest_t, phi)
        return phi

    def distance(self, x: np.ndarray) -> np.ndarray:
        return np.array([self.axis @ self._turn(x)])

    def jacobian(self, x: np.ndarray) -> JacobianRows:
        return JacobianRows(np.array([[self.node]]), self._row(x).reshape(1, 1, 3))

    def _row(self, x: np.ndarray, spin: np.ndarray | None = None) -> np.ndarray:
        """H^T of the node's orientation (3,), the node first turned by `spin`."""
        phi = self._turn(x)
        if spin is not None:
            r, turn = np.empty((3, 3)), np.empty((3, 3))
            rod_kernels.so3_exp(phi, r)
            rod_kernels.so3_exp(spin, turn)
            rod_kernels.so3_log(turn @ r, phi)
        jl_inv = np.empty((3, 3))
        rod_kernels.left_jacobian_inverse(phi, jl_inv)
        return self.axis @ jl_inv

    def load_stiffness_pairs(self) -> tuple[np.ndarray, np.ndarray]:
        """The one node pair of :meth:`load_stiffness`: the orientation with itself."""
        return np.array([self.node]), np.array([self.node])

    def load_stiffness(self, x: np.ndarray, torque: float) -> np.ndarray:
        """(1, 3, 3) -d(H^T lambda)/dx = -lambda d^2 delta/dx^2 on the orientation, by central
        differences of H^T over spins (step 6e-6 rad, error ~1e-10), symmetrised: a torque
        about a turns with the node in the other two directions. With it, the static solver's
        consistent tangent is the Hessian of the whole potential, symmetric at equilibrium."""
        h = 6e-6
        block = np.empty((3, 3))
        for k in range(3):
            step = np.zeros(3)
            step[k] = h
            block[:, k] = -torque * (self._row(x, step) - self._row(x, -step)) / (2.0 * h)
        return 0.5 * (block + block.T)[None]
