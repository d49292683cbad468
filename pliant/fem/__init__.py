"""Deformable bodies (tetrahedra, hexahedra, shells of triangles, rods, membranes),
materials, rigid bodies and the compiled kernels of their forces and tangents."""

from pliant.fem.body import TetBody, nodes_in_box
from pliant.fem.hexbody import HexBody
from pliant.fem.loads import (
    FollowerForce,
    Load,
    NodalForces,
    RestShapeSprings,
    SurfacePressure,
    SurfaceTraction,
)
from pliant.fem.material import MATERIALS, Corotational, Material, NeoHookean, StVenantKirchhoff
from pliant.fem.membrane import Membrane
from pliant.fem.rigid import (
    AttachedPoints,
    BodyForce,
    DrivenNodes,
    KinematicBody,
    RigidBody,
    motor,
    rail,
    servo,
)
from pliant.fem.rod import ClampedEnd, RodBody, RodSection
from pliant.fem.shell import PlaneStress, ShellBody, TriangleFEM
from pliant.fem.supports import OnLine, OnPlane, Projection

__all__ = [
    "MATERIALS",
    "AttachedPoints",
    "BodyForce",
    "ClampedEnd",
    "Corotational",
    "DrivenNodes",
    "FollowerForce",
    "HexBody",
    "KinematicBody",
    "Load",
    "Material",
    "Membrane",
    "NeoHookean",
    "StVenantKirchhoff",
    "NodalForces",
    "OnLine",
    "OnPlane",
    "PlaneStress",
    "Projection",
    "RestShapeSprings",
    "RigidBody",
    "RodBody",
    "RodSection",
    "ShellBody",
    "SurfacePressure",
    "SurfaceTraction",
    "TetBody",
    "TriangleFEM",
    "motor",
    "nodes_in_box",
    "rail",
    "servo",
]
