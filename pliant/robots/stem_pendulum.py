"""StemPendulum: a stiff stem hanging from a pivot, turned by a torque at its base (SofaGym
stempendulum-v0).

A Cosserat rod (:class:`pliant.fem.rod.RodBody`) hangs along -z from the origin, its base node
pinned (held in position, free to turn); a :class:`pliant.constraints.joint.RotationActuator`
in force mode applies a torque about +y to the base node's orientation, as a motor on the
pivot's shaft: the stem swings in the x-z plane under gravity. Two more rotation actuators in
displacement mode hold the base's turns about x and z at zero: with the pin they make a hinge
about y (a ball joint alone lets the stem fall out of its plane near the top). The torque is
bounded below the one that holds the stem horizontal (m g L / 2), so that swinging it up takes
several swings.
"""

from __future__ import annotations

import math

import numpy as np

from pliant.constraints.base import EmbeddedPoints
from pliant.constraints.effector import PositionEffector
from pliant.constraints.joint import RotationActuator
from pliant.errors import ModelError
from pliant.fem.rod import RodSection
from pliant.mesh.shapes import _require_positive, _require_whole
from pliant.model import Model
from pliant.robots.parameters import Damping, Density, Elastic, Gravity, Meshed
from pliant.robots.scene import builder


@builder(Meshed(), Elastic(5.0e4, 0.3), Density(1.0e-6), Gravity.Z, Damping(0.0, 1e-4))
def stem_pendulum(
    p,
    *,
    length: float = 100.0,
    width: float = 5.0,
    elements: int = 10,
    max_torque: float = 250.0,
) -> Model:
    """The stem hanging from its pivot at the origin, a torque motor on the pivot (actuator 0,
    force mode); actuators 1 and 2 are the hinge's held turns (commands 0).

    Args:
        mesh: a rod has none (a mesh given raises).
        length, width, elements: the stem (mm), square section, rod elements along it.
        young_modulus, poisson_ratio, density: its material (kPa, kg/mm^3); the default is a
            stiff plastic (50 MPa): the stem swings nearly as a rigid rod.
        rayleigh_mass, rayleigh_stiffness: damping; the default only damps the bending
            vibrations (none on the swing).
        max_torque: bound of the motor's torque (mN mm = kg mm^2/s^2, the units of mm, kg
            and s). SofaGym's 500 is in its own units; the default, 250 mN mm, is a fifth of
            m g L / 2 = 1226 mN mm, the torque that holds the default stem horizontal.
    """
    if p.mesh is not None:
        raise ModelError("the stem pendulum is a rod: it takes no mesh")
    _require_positive(length=length, width=width, max_torque=max_torque)
    _require_whole("elements", elements)
    n = int(elements)
    z = -np.linspace(0.0, length, n + 1)
    rod = p.rod_body(
        np.column_stack([np.zeros(n + 1), np.zeros(n + 1), z]),
        RodSection.rectangle(width, width),
        normal=(1.0, 0.0, 0.0),
        pinned=[0],
    )
    motor = RotationActuator(
        rod, 0, (0.0, 1.0, 0.0), name="motor", mode="force", max_force=max_torque
    )
    motor.min_force = -float(max_torque)
    hinge = [
        RotationActuator(rod, 0, axis, name=f"hinge_{label}", mode="displacement")
        for label, axis in (("x", (1.0, 0.0, 0.0)), ("z", (0.0, 0.0, 1.0)))
    ]
    tip = PositionEffector(EmbeddedPoints.at_nodes([n]), rod.rest_positions, name="tip")
    return Model(rod, actuators=[motor, *hinge], effectors=[tip], name="stem_pendulum")


def small_swing_period(length: float, gravity: float = 9810.0) -> float:
    """Period of small swings of a uniform rigid rod about one end: T = 2 pi sqrt(2 L / 3 g)
    (a compound pendulum of inertia m L^2 / 3, its centre of mass at L / 2)."""
    return 2.0 * math.pi * math.sqrt(2.0 * length / (3.0 * gravity))


def demo_actuation(t: float) -> np.ndarray:
    """Pump the swing: the full torque in the direction of the swing's small-angle motion,
    reversed every half period of the default stem (0.26 s)."""
    half = 0.5 * small_swing_period(100.0)
    return np.array([250.0 if int(t / half) % 2 == 0 else -250.0, 0.0, 0.0])
