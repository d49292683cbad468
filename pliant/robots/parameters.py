"""Parameter groups shared by the robot builders, declared once (issue #59): frozen
dataclasses of a robot's material, mass, gravity, damping, contacts, cables, mesh and objects,
each with a `keyword` (the name a builder takes the whole group by) and fields (the flat
keywords). :func:`pliant.robots.scene.builder` declares a builder's groups with its robot's
defaults.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar, Literal

from pliant.errors import ModelError
from pliant.fem.material import MATERIALS, Corotational, Material
from pliant.mesh.tetmesh import TetMesh

SILICONE_DENSITY = 1.07e-6  # kg / mm^3

MaterialName = Literal[
    "corotational", "corotational-large", "corotational-large-tolerant", "neo-hookean"
]

# Variants of the corotational law by name: SOFA's "large" element frames, and the same
# frames with inverted elements kept in the step, as SOFA runs them (see `Corotational`).
_VARIANTS = {
    "corotational-large": {"rotation": "large"},
    "corotational-large-tolerant": {"rotation": "large", "inversion": "tolerate"},
}


def make_material(name: str, young_modulus: float, poisson_ratio: float) -> Material:
    if name in _VARIANTS:
        return Corotational(young_modulus, poisson_ratio, **_VARIANTS[name])
    try:
        cls = MATERIALS[name]
    except KeyError:
        names = sorted([*MATERIALS, *_VARIANTS])
        raise ModelError(f"unknown material {name!r}; choose one of {names}") from None
    return cls(young_modulus, poisson_ratio)


@dataclass(frozen=True)
class Meshed:
    """A mesh in place of the robot's own (None: its own; a rod takes none)."""

    keyword: ClassVar[str] = "meshing"
    mesh: TetMesh | None = None


@dataclass(frozen=True)
class Meshing:
    """The size of the elements (mm) of the robot's own mesh, or a mesh in its place."""

    keyword: ClassVar[str] = "meshing"
    mesh_size: float = 8.0
    mesh: TetMesh | None = None


@dataclass(frozen=True)
class Elastic:
    """A linear elastic material: Young's modulus (kPa) and Poisson's ratio (rods)."""

    keyword: ClassVar[str] = "elastic"
    young_modulus: float
    poisson_ratio: float

    def law(self) -> Material:
        return Material(self.young_modulus, self.poisson_ratio)


@dataclass(frozen=True)
class Solid(Elastic):
    """A tetrahedral body's material: its elastic constants, the law by name
    (:func:`make_material`) and the mass matrix ("lumped" or "uniform")."""

    keyword: ClassVar[str] = "solid"
    material: MaterialName = "corotational"
    mass: str = "lumped"

    def law(self) -> Material:
        return make_material(self.material, self.young_modulus, self.poisson_ratio)


@dataclass(frozen=True)
class Density:
    """The body's mass given by its density (kg/mm^3)."""

    keyword: ClassVar[str] = "inertia"
    density: float = SILICONE_DENSITY


@dataclass(frozen=True)
class TotalMass:
    """The body's mass given in total (kg)."""

    keyword: ClassVar[str] = "inertia"
    total_mass: float


@dataclass(frozen=True)
class Gravity:
    """The gravity vector (mm/s^2)."""

    keyword: ClassVar[str] = "gravity"
    gravity: tuple[float, float, float] = (0.0, 0.0, -9810.0)

    Z: ClassVar[Gravity]
    NONE: ClassVar[Gravity]


Gravity.Z = Gravity()
Gravity.NONE = Gravity((0.0, 0.0, 0.0))


@dataclass(frozen=True)
class Damping:
    """Rayleigh damping: the mass factor (1/s) and the stiffness factor (s)."""

    keyword: ClassVar[str] = "damping"
    rayleigh_mass: float = 0.0
    rayleigh_stiffness: float = 0.0


@dataclass(frozen=True)
class Contact:
    """Coulomb friction of the body's contacts and their detection distance (mm)."""

    keyword: ClassVar[str] = "contact"
    friction: float = 0.0
    contact_margin: float = 3.0


@dataclass(frozen=True)
class ContactSolver:
    """The contacts' detection distance (mm), the solver's tolerance (mm) and its sweeps at
    most."""

    keyword: ClassVar[str] = "contact_solver"
    contact_margin: float = 3.0
    contact_tolerance: float = 2e-4
    contact_iterations: int = 3000


@dataclass(frozen=True)
class Cables:
    """The cables' control mode ("displacement" or "force") and bounds: force (mN) and
    displacement change per step (mm, None: unbounded); each robot bounds their
    displacements itself."""

    keyword: ClassVar[str] = "cables"
    cable_mode: str = "displacement"
    max_cable_force: float = math.inf
    max_displacement_change: float | None = None


@dataclass(frozen=True)
class CableReach:
    """The Trunk's cable displacement bounds (mm): its four long cables and four short ones."""

    keyword: ClassVar[str] = "reach"
    max_long_displacement: float = 70.0
    max_short_displacement: float = 40.0

    def limits(self) -> list[float]:
        return [self.max_long_displacement] * 4 + [self.max_short_displacement] * 4


@dataclass(frozen=True)
class Cube:
    """A rigid cube's edge (mm) and mass (kg)."""

    keyword: ClassVar[str] = "cube"
    cube_size: float = 30.0
    cube_mass: float = 0.01


@dataclass(frozen=True)
class Ball:
    """A rigid ball's radius (mm) and mass (kg)."""

    keyword: ClassVar[str] = "ball"
    ball_radius: float = 10.0
    ball_mass: float = 0.003
