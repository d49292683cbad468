"""Constraints in the compliance space: actuators, effectors, contacts and friction, and the
direct and inverse problems that choose their forces."""

from pliant.constraints.attachment import Attachment, Weld
from pliant.constraints.base import Actuator, Constraint, EmbeddedPoints
from pliant.constraints.cable import CableActuator, CableBundle
from pliant.constraints.cavity import CavityActuator
from pliant.constraints.contact import Contacts
from pliant.constraints.control import DirectControl, InverseControl
from pliant.constraints.effector import PositionEffector, RigidEffector
from pliant.constraints.joint import RotationActuator
from pliant.constraints.point import PointActuator
from pliant.constraints.surface import RigidSurfaceContact, SurfaceContact, body_pieces

__all__ = [
    "Actuator",
    "Attachment",
    "CableActuator",
    "CableBundle",
    "CavityActuator",
    "Constraint",
    "Contacts",
    "DirectControl",
    "EmbeddedPoints",
    "InverseControl",
    "PointActuator",
    "PositionEffector",
    "RigidEffector",
    "RotationActuator",
    "RigidSurfaceContact",
    "SurfaceContact",
    "Weld",
    "body_pieces",
]
