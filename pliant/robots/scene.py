"""How a robot builder is declared: the parameter groups it takes (issue #59).

A builder declares the groups it takes (:mod:`pliant.robots.parameters`), with its robot's
defaults, and only its own keywords::

    @builder(Meshing(13.0), Solid(180.0, 0.45, mass="uniform"), TotalMass(0.5), Gravity.Z)
    def diamond(p, *, max_cable_displacement: float = 20.0) -> Model:
        mesh = p.mesh_or(shapes.diamond)
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
import typing
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from pliant.constraints.contact import Contacts
from pliant.errors import ModelError
from pliant.fem.body import TetBody
from pliant.fem.material import Material
from pliant.fem.rod import RodBody, RodSection
from pliant.mesh.tetmesh import TetMesh
from pliant.robots.parameters import Damping, Meshing


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

    def mesh_or(self, make: Callable[..., TetMesh], **keywords) -> TetMesh:
        """The mesh given, or the robot's own: make(**keywords), with the mesh_size of a
        `Meshing` group."""
        if self.mesh is not None:
            return self.mesh
        if isinstance(self.meshing, Meshing):
            keywords["mesh_size"] = self.mesh_size
        return make(**keywords)

    def _mass_keywords(self) -> dict[str, object]:
        return {f.name: getattr(self.inertia, f.name) for f in dataclasses.fields(self.inertia)}

    def loads(self) -> dict[str, object]:
        """The body keywords of the gravity and damping groups (no damping group: none)."""
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
            **self.loads(),
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
            **self.loads(),
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
