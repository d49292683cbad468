"""The Trunk catching a free-floating cube in zero gravity: space debris (thesis §3.2.2,
Fig. 3.10).

The Trunk of :mod:`pliant.robots.trunk` (along +z, its base held over its first 20 mm) is
mounted on a spacecraft's hull, the plane z = 0; nothing weighs. A rigid cube floats at rest
beside its distal half, on the +x side by default. Pulling the +x cables bends the trunk
towards the cube; wrapping it catches the cube, a push sends it drifting away.
"""

from __future__ import annotations

import math

import numpy as np

from pliant.fem.body import TetBody
from pliant.fem.rigid import RigidBody
from pliant.geometry.collision import Box, Plane
from pliant.mesh.shapes import _require_positive
from pliant.model import Model
from pliant.robots.parameters import Contact, Cube, Gravity, Meshing
from pliant.robots.scene import builder
from pliant.robots.trunk import TRUNK
from pliant.robots.trunk_cube import trunk_scene

LENGTH = 195.0
BASE_RADIUS, TIP_RADIUS = 13.0, 5.0


def trunk_radius(z: float) -> float:
    """Outer radius of the default Trunk at height z (its cone: 13 mm at the base, 5 at the
    tip)."""
    return BASE_RADIUS + (TIP_RADIUS - BASE_RADIUS) * z / LENGTH


def beside_trunk(size: float, z: float, gap: float, azimuth: float = 0.0) -> np.ndarray:
    """Centre of a cube of `size` mm at height z whose face towards the trunk's axis is `gap` mm
    from its surface, in the direction `azimuth` (rad, from +x towards +y)."""
    distance = trunk_radius(z) + gap + size / 2
    return np.array([distance * math.cos(azimuth), distance * math.sin(azimuth), z])


@builder(Meshing(8.0), *TRUNK[:2], Gravity.NONE, *TRUNK[3:], Contact(0.5, 5.0), Cube(30.0, 0.01))
def trunk_space_debris(
    p,
    *,
    cube_damping: float = 0.0,
    cube_position: tuple[float, float, float] | None = None,
    cube_rotation: np.ndarray | None = None,
) -> Model:
    """The Trunk (SoftRobots parameters, coarse mesh by default, no gravity) and a rigid cube
    of `cube_size` mm and `cube_mass` kg floating at rest at `cube_position` (default: 10 mm
    from the trunk's surface on +x at z = 150 mm; see :func:`beside_trunk`). `cube_damping`
    (1/s) damps the cube's linear and angular velocity (a force -c m v, a torque -c I w), as a
    SOFA rigid object under a solver with rayleighMass = c would be; 0 (default): a pushed
    cube drifts on.

    Give `mesh` (a :func:`pliant.mesh.shapes.trunk` mesh) to build several scenes on one
    Trunk mesh, e.g. one per cube size.
    """
    cube_size, cube_mass = p.cube.cube_size, p.cube.cube_mass
    _require_positive(cube_size=cube_size, cube_mass=cube_mass)

    def cube(body: TetBody) -> tuple[list[RigidBody], None]:
        half = cube_size / 2
        position = beside_trunk(cube_size, 150.0, 10.0) if cube_position is None else cube_position
        box = Box([half, half, half], position=position, rotation=cube_rotation)
        rigid = RigidBody(
            box,
            cube_mass,
            friction=p.contact.friction,
            linear_damping=cube_damping,
            angular_damping=cube_damping,
            name="cube",
        )
        return [rigid], None

    return trunk_scene(
        p,
        base_motion=None,
        obstacle=Plane(normal=(0.0, 0.0, 1.0), point=(0.0, 0.0, 0.0)),  # the hull
        objects=cube,
        name="trunk_space_debris",
    )


def demo_actuation(t: float) -> np.ndarray:
    """Curl towards the cube: the long +x cable (3) to 40 mm and the short one (7) to 20 mm
    over 1 s, held: the distal half wraps the cube's near face."""
    values = np.zeros(8)
    values[3] = 40.0 * min(t, 1.0)
    values[7] = 20.0 * min(t, 1.0)
    return values
