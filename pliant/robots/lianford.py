"""The Lianford: a soft parallel robot of six deformable legs, each turned at its base by a DC
motor, the effector a central handle (thesis §5.2.5, Fig. 5.22; a lattice of beam elements).

Six Cosserat rod legs (:class:`pliant.fem.rod.RodBody`, one lattice) rise from base points on
a circle to a ring round the handle; spokes weld each leg's top to the handle node. Each leg's
base is pinned (held in position) and turned about the horizontal tangent of the base circle
by its motor (:class:`pliant.constraints.joint.RotationActuator`): a servo in angle mode by
default (command: the shaft's angle, rad), or a torque motor (mN mm). Turning a base swings its
leg in or out; the legs together move and tilt the handle. The handle node is the effector;
`orientation_effectors` adds the ring's two points on the x axis (legs 0 and 3), whose
positions give the handle's orientation.
"""

from __future__ import annotations

import math
from typing import Literal

import numpy as np

from pliant.constraints.base import EmbeddedPoints
from pliant.constraints.effector import PositionEffector
from pliant.constraints.joint import RotationActuator
from pliant.errors import ModelError
from pliant.fem.rod import RodSection
from pliant.mesh.shapes import require_arguments
from pliant.model import Model
from pliant.robots.parameters import Damping, Density, Elastic, Gravity, Meshed
from pliant.robots.scene import builder


def leg_nodes(legs: int, elements: int, base_radius: float, top_radius: float, height: float):
    """Points of the lattice (handle first, then each leg base to top), its elements (each leg
    then its spoke to the handle), the base node of each leg and its motor's axis."""
    points, pairs, bases, axes = [[0.0, 0.0, height]], [], [], []
    for i in range(legs):
        a = 2.0 * math.pi * i / legs
        radial = np.array([math.cos(a), math.sin(a), 0.0])
        base, top = base_radius * radial, top_radius * radial + [0.0, 0.0, height]
        first = len(points)
        points += [list((1.0 - s) * base + s * top) for s in np.linspace(0.0, 1.0, elements + 1)]
        pairs += [[first + j, first + j + 1] for j in range(elements)] + [[first + elements, 0]]
        bases.append(first)
        axes.append([-radial[1], radial[0], 0.0])
    return np.array(points), np.array(pairs), bases, np.array(axes)


@builder(Meshed(), Elastic(2.0e4, 0.4), Density(1.2e-6), Gravity.Z, Damping(2.0, 0.0))
def lianford(
    p,
    *,
    legs: int = 6,
    elements: int = 6,
    base_radius: float = 60.0,
    top_radius: float = 15.0,
    height: float = 70.0,
    leg_radius: float = 2.0,
    motor_mode: Literal["angle", "torque"] = "angle",
    max_angle: float = 0.6,
    max_torque: float = 5.0e4,
    orientation_effectors: bool = False,
) -> Model:
    """The Lianford standing on the plane z = 0, the handle at `height` above the centre.

    Args:
        legs, elements: legs (>= 3) and rod elements per leg.
        base_radius, top_radius, height: base circle, ring round the handle, handle height (mm).
        leg_radius: the legs' (and spokes') circular section (mm).
        young_modulus, poisson_ratio, density: a stiff elastomer (20 MPa; kPa, kg/mm^3).
        motor_mode: "angle" (servos: commands are shaft angles, |angle| <= max_angle rad) or
            "torque" (commands are torques, |torque| <= max_torque mN mm). Either way the
            torque is bounded by max_torque, which the trajectory optimisation uses as u.
        orientation_effectors: also put effectors on the ring at +x and -x.
    """
    if p.mesh is not None:
        raise ModelError("the Lianford is a rod lattice: it takes no mesh")
    require_arguments(
        locals(),
        "base_radius top_radius height leg_radius max_angle max_torque",
        legs=3,
        elements=1,
    )
    if motor_mode not in ("angle", "torque"):
        raise ModelError(f"motor_mode must be 'angle' or 'torque', got {motor_mode!r}")
    points, pairs, bases, axes = leg_nodes(
        int(legs), int(elements), base_radius, top_radius, height
    )
    body = p.rod_body(points, RodSection.circle(leg_radius), elements=pairs, pinned=bases)
    mode = "displacement" if motor_mode == "angle" else "force"
    motors = [
        RotationActuator(
            body,
            b,
            ax,
            name=f"motor_{i}",
            mode=mode,
            min_force=-max_torque,
            max_force=max_torque,
            min_displacement=-max_angle,
            max_displacement=max_angle,
        )
        for i, (b, ax) in enumerate(zip(bases, axes, strict=True))
    ]
    effectors = [PositionEffector(EmbeddedPoints.at_nodes([0]), body.rest_positions, name="handle")]
    if orientation_effectors:
        tops = [bases[0] + int(elements), bases[len(bases) // 2] + int(elements)]
        effectors += [
            PositionEffector(EmbeddedPoints.at_nodes([n]), body.rest_positions, name=name)
            for n, name in zip(tops, ("ring_x+", "ring_x-"), strict=True)
        ]
    return Model(body, actuators=motors, effectors=effectors, name="lianford")


def demo_actuation(t: float) -> np.ndarray:
    """Servo angles (rad) of a wave round the legs: the handle circles."""
    phase = 2.0 * math.pi * np.arange(6) / 6
    return 0.2 * min(t, 1.0) * np.sin(2.0 * math.pi * t - phase)


def spiral(n: int = 40, *, radius: float = 4.0, turns: float = 2.0, drop: float = 2.0):
    """Goals round the rest handle (0, 0, 70 mm), a spiral of growing radius going down by
    `drop` (inverse control; the motors cannot lift the handle much above its rest)."""
    s = np.linspace(0.0, 1.0, n)
    a = 2.0 * math.pi * turns * s
    return np.column_stack([radius * s * np.cos(a), radius * s * np.sin(a), 70.0 - drop * s])
