"""Constitutive laws of the tetrahedral bodies.

A material is a small immutable object: its Lamé parameters and an integer tag that the
compiled kernels (:mod:`pliant.fem.kernels`) dispatch on.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass
from typing import ClassVar

from pliant.errors import MaterialError

COROTATIONAL = 0
NEO_HOOKEAN = 1


@dataclass(frozen=True)
class Material:
    """Isotropic elastic material given by Young's modulus and Poisson's ratio.

    Args:
        young_modulus: E > 0, in the scene's stress unit (kPa for mm-kg-s scenes).
        poisson_ratio: 0 <= nu < 0.5.
    """

    young_modulus: float
    poisson_ratio: float
    kernel_tag: ClassVar[int] = -1

    def __post_init__(self) -> None:
        e, nu = self.young_modulus, self.poisson_ratio
        if not (_is_real(e) and math.isfinite(e)) or e <= 0:
            raise MaterialError(f"Young's modulus must be finite and > 0, got {e!r}")
        if not (_is_real(nu) and math.isfinite(nu)) or not 0 <= nu < 0.5:
            raise MaterialError(
                f"Poisson's ratio must lie in [0, 0.5), got {nu!r}"
                " (0.5 is incompressible and makes the Lamé parameter lambda infinite)"
            )
        # NumPy scalars (np.float32(180), np.int64(180)) are numbers too: kept as floats.
        object.__setattr__(self, "young_modulus", float(e))
        object.__setattr__(self, "poisson_ratio", float(nu))

    @property
    def mu(self) -> float:
        """Shear modulus (second Lamé parameter)."""
        return self.young_modulus / (2.0 * (1.0 + self.poisson_ratio))

    @property
    def lam(self) -> float:
        """First Lamé parameter."""
        nu = self.poisson_ratio
        return self.young_modulus * nu / ((1.0 + nu) * (1.0 - 2.0 * nu))


@dataclass(frozen=True)
class Corotational(Material):
    """Corotational linear elasticity (SOFA's TetrahedronFEMForceField, polar rotation).

    Energy density psi(F) = mu |S - I|^2 + lam/2 tr(S - I)^2 with F = R S the polar
    decomposition, so that P = R (2 mu (S - I) + lam tr(S - I) I) is its exact gradient.
    The linearisation used by the solvers is SOFA's R K0 R^T (symmetric positive definite);
    the exact tangent, which adds the variation of R, is available for verification.
    """

    kernel_tag: ClassVar[int] = COROTATIONAL


@dataclass(frozen=True)
class NeoHookean(Material):
    """Compressible Neo-Hookean law (Bonet & Wood, Eq. 6.28).

    psi(F) = mu/2 (tr(F^T F) - 3) - mu ln J + lam/2 (ln J)^2, J = det F.
    """

    kernel_tag: ClassVar[int] = NEO_HOOKEAN


def _is_real(value) -> bool:
    """A real number of any kind (int, float, NumPy scalar), not a bool."""
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


MATERIALS: dict[str, type[Material]] = {
    "corotational": Corotational,
    "neo-hookean": NeoHookean,
}
