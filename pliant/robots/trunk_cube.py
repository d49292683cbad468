"""The Trunk pushing a rigid cube on a plane (thesis §4.1.2: "a rigid cube that can glide on a
rigid planar surface, and the base of the trunk can translate in one direction").

The Trunk of :mod:`pliant.robots.trunk` lies along +z under gravity -y, above a floor; its
base is held by a carriage that translates along the trunk's axis (driven nodes). The cables
start from their pull points on the base plane, which are embedded in the held base (carried
with it, as the motors are) rather than fixed in space. A rigid cube rests on the floor beside
the trunk's distal half, on the +x side: pulling the +x cable bends the trunk onto it and pushes
it along the floor.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from pliant.constraints.base import EmbeddedPoints
from pliant.constraints.cable import CableActuator
from pliant.constraints.collision import Box, Plane
from pliant.constraints.contact import Contacts
from pliant.fem.rigid import DrivenNodes, KinematicBody, RigidBody, rail
from pliant.mesh.tetmesh import TetMesh
from pliant.model import Model
from pliant.robots.common import MaterialName, landmark, smooth_ramp
from pliant.robots.trunk import reference_cable_paths, trunk


def demo_base_motion(t: float) -> float:
    """Advance the base by 20 mm along the trunk's axis between 1 s and 2 s."""
    return 20.0 * smooth_ramp(t, 1.0, 1.0)


def trunk_cube(
    *,
    mesh: TetMesh | None = None,
    mesh_size: float = 8.0,
    young_modulus: float = 450.0,
    poisson_ratio: float = 0.45,
    total_mass: float = 0.042,
    material: MaterialName = "corotational",
    rayleigh_mass: float = 0.1,
    rayleigh_stiffness: float = 0.1,
    cable_mode: str = "displacement",
    max_long_displacement: float = 70.0,
    max_short_displacement: float = 40.0,
    max_displacement_change: float | None = 1.0,
    cube_size: float = 30.0,
    cube_mass: float = 0.01,
    cube_position: tuple[float, float] = (30.0, 150.0),
    floor_height: float = -30.0,
    friction: float = 0.3,
    base_motion: Callable[[float], float] = demo_base_motion,
) -> Model:
    """The Trunk (SoftRobots parameters, coarser mesh by default) over a floor y = floor_height,
    a rigid cube of `cube_size` mm and `cube_mass` kg on it at (x, z) = `cube_position`, the
    base moving along z by `base_motion(t)` (mm)."""
    arm = trunk(
        mesh=mesh,
        mesh_size=mesh_size,
        young_modulus=young_modulus,
        poisson_ratio=poisson_ratio,
        total_mass=total_mass,
        material=material,
        rayleigh_mass=rayleigh_mass,
        rayleigh_stiffness=rayleigh_stiffness,
    )
    body = arm.body
    mesh = body.mesh
    paths, pulls = reference_cable_paths()
    limits = [max_long_displacement] * 4 + [max_short_displacement] * 4
    cables = [
        CableActuator(
            EmbeddedPoints(
                mesh,
                np.vstack(
                    [
                        landmark(mesh, f"pull_points_{i}", pulls[i]),
                        landmark(mesh, f"cable_points_{i}", paths[i]),
                    ]
                ),
            ),
            body.rest_positions,
            name=f"cable_{i}",
            mode=cable_mode,
            min_force=0.0,
            max_force=math.inf,
            max_displacement=limits[i],
            max_displacement_change=max_displacement_change,
        )
        for i in range(8)
    ]
    carriage = KinematicBody(
        Box([20.0, 20.0, 5.0], position=[0.0, 0.0, -5.0]),
        rail([0.0, 0.0, -5.0], [0.0, 0.0, 1.0], base_motion),
        name="carriage",
    )
    half = cube_size / 2
    x, z = cube_position
    cube = RigidBody(
        Box([half, half, half], position=[x, floor_height + half, z]),
        cube_mass,
        friction=friction,
        name="cube",
    )
    floor = Plane(normal=(0.0, 1.0, 0.0), point=(0.0, floor_height, 0.0))
    return Model(
        body,
        actuators=cables,
        effectors=arm.effectors,
        contacts=Contacts([floor], friction=friction, margin=3.0),
        drivers=[DrivenNodes(body.fixed_nodes, carriage, name="carriage")],
        rigid_bodies=[cube],
        name="trunk_cube",
    )


def demo_actuation(t: float) -> np.ndarray:
    """Pull the long +x cable (cable 3) to 25 mm over 1 s: the trunk bends onto the cube."""
    values = np.zeros(8)
    values[3] = 25.0 * min(t, 1.0)
    return values
