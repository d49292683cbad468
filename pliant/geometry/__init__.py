"""Geometry below the bodies and the contacts: rotations, collision shapes with their signed
distances and the detection of contacts between them, and the inertia of solid shapes."""

from pliant.geometry.collision import (
    Box,
    BoxUnion,
    Capsule,
    ContactSet,
    Plane,
    Shape,
    SignedDistance,
    Sphere,
    TriangleMesh,
    collide,
    detect,
)
from pliant.geometry.inertia import (
    box_inertia,
    box_union_inertia,
    capsule_inertia,
    cylinder_inertia,
    sphere_inertia,
)

__all__ = [
    "Box",
    "BoxUnion",
    "Capsule",
    "ContactSet",
    "Plane",
    "Shape",
    "SignedDistance",
    "Sphere",
    "TriangleMesh",
    "box_inertia",
    "box_union_inertia",
    "capsule_inertia",
    "collide",
    "cylinder_inertia",
    "detect",
    "sphere_inertia",
]
