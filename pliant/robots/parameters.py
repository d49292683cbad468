"""Parameter groups shared by the robot builders, declared once (issue #59).

A builder declares the groups it takes, with its robot's defaults, in one line::

    @builder(Solid(180.0, 0.45, mass="uniform"), TotalMass(0.5), Gravity.Z, Damping())
    def diamond(p, *, mesh: TetMesh | None = None, ...) -> Model:
        body = p.tet_body(mesh, fixed_nodes=...)

and is called as before, with flat keywords (``diamond(young_modulus=200.0)``,
``build("diamond", rayleigh_mass=0.1)``), or with whole groups
(``diamond(solid=Solid(200.0, 0.45))``); the builder receives the groups in `p`. The
builder's signature (what :func:`inspect.signature` and :func:`pliant.robots.build` read)
lists the flat keywords with the robot's defaults and their type hints.
"""

from __future__ import annotations

import dataclasses
import functools
import inspect
import math
import typing
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import ClassVar, Literal

from pliant.constraints.contact import Contacts
from pliant.errors import ModelError
from pliant.fem.body import TetBody
from pliant.fem.material import MATERIALS, Corotational, Material
from pliant.fem.rod import RodBody, RodSection
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


@dataclass(frozen=True)
class Shared:
    """The groups a builder was called with, by keyword (`p.solid`, `p.inertia`, ...), and the
    bodies and contacts made of them."""

    groups: dict[str, object]

    def __getattr__(self, name: str):
        try:
            return self.groups[name]
        except KeyError:
            raise AttributeError(name) from None

    @property
    def mesh(self) -> TetMesh | None:
        """The mesh given in place of the robot's own, or None."""
        return self.meshing.mesh

    @property
    def mesh_size(self) -> float:
        return self.meshing.mesh_size

    def _mass_keywords(self) -> dict[str, object]:
        return {f.name: getattr(self.inertia, f.name) for f in dataclasses.fields(self.inertia)}

    def _loads(self) -> dict[str, object]:
        keywords: dict[str, object] = {}
        if "gravity" in self.groups:
            keywords["gravity"] = self.gravity.gravity
        damping = self.groups.get("damping", Damping())
        keywords["rayleigh_mass"] = damping.rayleigh_mass
        keywords["rayleigh_stiffness"] = damping.rayleigh_stiffness
        return keywords

    def tet_body(self, mesh: TetMesh, **extra) -> TetBody:
        """A :class:`TetBody` of `mesh` with the groups' material, mass, gravity and damping
        (`extra`: fixed_nodes, membranes, ...)."""
        return TetBody(
            mesh,
            self.solid.law(),
            **self._mass_keywords(),
            mass=self.solid.mass,
            **self._loads(),
            **extra,
        )

    def rod_body(self, points, section: RodSection, **extra) -> RodBody:
        """A :class:`RodBody` along `points` with the groups' material, mass, gravity and
        damping (`extra`: normal, clamped, pinned, elements, ...)."""
        elastic = self.groups.get("elastic", self.groups.get("solid"))
        return RodBody(
            points,
            section,
            Material(elastic.young_modulus, elastic.poisson_ratio),
            **self._mass_keywords(),
            **extra,
            **self._loads(),
        )

    def contacts(self, obstacles: Sequence, **extra) -> Contacts:
        """:class:`Contacts` with `obstacles` at the group's friction and margin."""
        return Contacts(
            obstacles, friction=self.contact.friction, margin=self.contact.contact_margin, **extra
        )


def _fields(group) -> tuple[dataclasses.Field, ...]:
    return dataclasses.fields(group)


def builder(*defaults) -> Callable[[Callable], Callable]:
    """Make a builder `f(p, *, ...)` take the groups `defaults` (one per keyword) by flat
    keywords (their fields) or whole (their `keyword`), and pass them to `f` as `p`
    (:class:`Shared`). A group of one field named as its keyword (`gravity`) takes either."""
    by_keyword = {type(g).keyword: g for g in defaults}
    if len(by_keyword) != len(defaults):
        raise TypeError("a builder takes one group per keyword")
    owner = {f.name: k for k, g in by_keyword.items() for f in _fields(g)}
    if len(owner) != sum(len(_fields(g)) for g in defaults):
        raise TypeError("two groups of a builder share a keyword")

    def decorate(f: Callable) -> Callable:
        own = list(inspect.signature(f).parameters.values())[1:]
        clash = {p.name for p in own} & (set(owner) | set(by_keyword))
        if clash:
            raise TypeError(f"{f.__name__} re-declares shared keywords {sorted(clash)}")
        hints = typing.get_type_hints(f)
        flat = []
        for g in by_keyword.values():
            group_hints = typing.get_type_hints(type(g))
            for field in _fields(g):
                flat.append(
                    inspect.Parameter(
                        field.name,
                        inspect.Parameter.KEYWORD_ONLY,
                        default=getattr(g, field.name),
                        annotation=group_hints[field.name],
                    )
                )
                hints[field.name] = group_hints[field.name]
        hints.pop(next(iter(inspect.signature(f).parameters)), None)

        @functools.wraps(f)
        def build(**kwargs):
            groups = {}
            for keyword, default in by_keyword.items():
                given = kwargs.pop(keyword, None) if keyword not in owner else None
                if given is not None and not isinstance(given, type(default)):
                    raise ModelError(
                        f"{f.__name__}: {keyword} must be a {type(default).__name__}, got {given!r}"
                    )
                groups[keyword] = given if given is not None else default
            for name in [k for k in kwargs if k in owner]:
                keyword, value = owner[name], kwargs.pop(name)
                if keyword == name and isinstance(value, type(by_keyword[keyword])):
                    groups[keyword] = value
                else:
                    groups[keyword] = dataclasses.replace(groups[keyword], **{name: value})
            return f(Shared(groups), **kwargs)

        del build.__wrapped__
        build.__signature__ = inspect.Signature(
            own + flat, return_annotation=inspect.signature(f).return_annotation
        )
        build.__annotations__ = hints
        build.defaults = by_keyword
        return build

    return decorate


def variant(base: Callable, name: str, doc: str, **defaults) -> Callable:
    """`base` with other defaults: a builder of the same keywords named `name`."""
    signature = inspect.signature(base)
    unknown = set(defaults) - set(signature.parameters)
    if unknown:
        raise TypeError(f"{base.__name__} has no keywords {sorted(unknown)}")

    def build(**kwargs):
        return base(**{**defaults, **kwargs})

    build.__name__ = build.__qualname__ = name
    build.__module__ = base.__module__
    build.__doc__ = doc
    build.__signature__ = signature.replace(
        parameters=[
            p.replace(default=defaults[p.name]) if p.name in defaults else p
            for p in signature.parameters.values()
        ]
    )
    build.__annotations__ = dict(base.__annotations__)
    return build
