"""Constitutive laws of the tetrahedral bodies, and the Coulomb friction coefficients of
contacts.

A material is a small immutable object: its Lamé parameters and an integer tag that the
compiled kernels (:mod:`pliant.fem.kernels`) dispatch on.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass
from typing import ClassVar, Literal

import numpy as np

from pliant.errors import ContactError, MaterialError

COROTATIONAL = 0
NEO_HOOKEAN = 1
COROTATIONAL_LARGE = 2
COROTATIONAL_LARGE_INVERTIBLE = 3  # "large" frames, inverted elements keep their force
ST_VENANT_KIRCHHOFF = 4

Rotation = Literal["polar", "large"]
Inversion = Literal["refuse", "tolerate"]


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
    tolerates_inversion: ClassVar[bool] = False

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
    """Corotational linear elasticity (SOFA's TetrahedronFEMForceField).

    P = R (2 mu eps + lam tr(eps) I), eps = sym(R^T F) - I, with the element rotation R:

    * ``rotation="polar"`` (SOFA's ``method="polar"``): F = R S, the polar decomposition.
      Energy density psi(F) = mu |S - I|^2 + lam/2 tr(S - I)^2, of which P is the exact
      gradient.
    * ``rotation="large"`` (SOFA's default ``method="large"``, the one every SoftRobots scene
      uses): R = Q(x) Q(X)^T with Q the orthonormal frame of the element's edges, first axis
      along x_1 - x_0, third normal to the plane of x_0, x_1, x_2 (the element's own node
      order). P is the gradient of the same psi with R frozen; it is the gradient of psi(F)
      only where R^T F is symmetric (the edge frame is then the polar one: rest, rigid
      motions, stretches along the frame's axes), and to first order in the strain
      elsewhere.

    ``inversion="tolerate"`` (large frames only) is SOFA's behaviour at an inverted element
    (det F <= 0): the edge frame is a rotation whatever the element's orientation, so the
    element keeps its force, which pulls it back towards its rest shape, and the step goes on.
    With ``"refuse"`` (the default) an inverted element is a divergence (``DivergenceError``,
    cause ``"inverted"``): its state is not a deformation. Tolerating it lets a coarse mesh
    follow a load that locally exceeds what its elements can represent (a cable's last
    point pulled on one node), as SOFA's scenes do; the polar frame of an inverted F is a
    reflection, so ``"polar"`` cannot tolerate inversion.

    The linearisation used by the dynamic step is SOFA's R K0 R^T (symmetric positive definite)
    for both. The exact tangent of the polar law, which adds the variation of R, is what the
    static Newton solve factorises (``StaticSolver(consistent=True)``); the large-frame forces
    are not a gradient, their exact Jacobian is not symmetric, and the static solve uses R K0 R^T
    for them too (Newton then converges linearly, as SOFA's own static solve does).
    """

    rotation: Rotation = "polar"
    inversion: Inversion = "refuse"

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.rotation not in ("polar", "large"):
            raise MaterialError(
                f"the corotational rotation is 'polar' or 'large', got {self.rotation!r}"
            )
        if self.inversion not in ("refuse", "tolerate"):
            raise MaterialError(f"inversion is 'refuse' or 'tolerate', got {self.inversion!r}")
        if self.inversion == "tolerate" and self.rotation != "large":
            raise MaterialError(
                "inversion='tolerate' needs rotation='large': the polar rotation of an inverted"
                " element is a reflection"
            )

    @property
    def kernel_tag(self) -> int:  # type: ignore[override]
        if self.rotation == "polar":
            return COROTATIONAL
        return COROTATIONAL_LARGE_INVERTIBLE if self.inversion == "tolerate" else COROTATIONAL_LARGE

    @property
    def tolerates_inversion(self) -> bool:
        return self.inversion == "tolerate"


@dataclass(frozen=True)
class NeoHookean(Material):
    """Compressible Neo-Hookean law (Bonet & Wood, Eq. 6.28).

    psi(F) = mu/2 (tr(F^T F) - 3) - mu ln J + lam/2 (ln J)^2, J = det F.
    """

    kernel_tag: ClassVar[int] = NEO_HOOKEAN


@dataclass(frozen=True)
class StVenantKirchhoff(Material):
    """St Venant-Kirchhoff law (SOFA's ``materialName="StVenantKirchhoff"``).

    psi(F) = lam/2 tr(E)^2 + mu E:E, E = (F^T F - I) / 2: the first Piola stress is
    P = F (lam tr(E) I + 2 mu E). Linear elasticity in the Green strain: frame-independent and
    exact under rigid motions, it softens in strong compression (its energy has no barrier at
    J = 0; an inverted element is a divergence, as for every law but the tolerant large frame).
    """

    kernel_tag: ClassVar[int] = ST_VENANT_KIRCHHOFF


def _is_real(value) -> bool:
    """A real number of any kind (int, float, NumPy scalar), not a bool."""
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


MATERIALS: dict[str, type[Material]] = {
    "corotational": Corotational,
    "neo-hookean": NeoHookean,
}


def check_friction(friction, n_contacts: int) -> np.ndarray:
    """mu as a (k,) array from a scalar or k values; ContactError if any is < 0 or not finite."""
    values = np.asarray(friction, dtype=float).reshape(-1)
    if values.size not in (1, n_contacts):
        raise ContactError(f"expected 1 or {n_contacts} friction coefficients, got {values.size}")
    # Two reductions in the usual case (a step's contact solve checks its coefficients).
    if not (values.size and math.isfinite(values.sum()) and values.min() >= 0.0):
        bad = ~(np.isfinite(values) & (values >= 0.0))
        if np.any(bad):
            i = int(np.argmax(bad))
            raise ContactError(
                f"friction coefficients must be finite and >= 0, got mu = {float(values[i])}"
                f" (contact {i})"
            )
    return values.copy() if values.size == n_contacts else np.full(n_contacts, values[0])
