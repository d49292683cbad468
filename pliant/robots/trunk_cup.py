"""The Trunk with a cup (thesis §3.3.2, Fig. 3.13; SofaGym trunkcup-v0).

The Trunk of :mod:`pliant.robots.trunk_cube` (lying along +z under gravity -y, its base on a
carriage that translates along the trunk's axis) over a rigid cup standing upright on the
floor, under its distal part. The cup is a closed triangle mesh, the solid of revolution of its
wall and bottom (SofaGym's cup is deformable, E = 1000 kPa; Pliant's model holds one deformable
body, so this one is rigid). Curling the trunk down (its -y cable) hooks its distal end over
the cup's far wall and drags the cup back along the floor; moving the carriage back drags it
further.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from pliant.errors import ModelError
from pliant.fem.body import TetBody
from pliant.fem.rigid import RigidBody
from pliant.geometry.collision import TriangleMesh
from pliant.mesh.shapes import _require_positive, _require_whole
from pliant.model import Model
from pliant.robots.common import smooth_ramp
from pliant.robots.parameters import Contact, Meshing, Solid
from pliant.robots.scene import builder
from pliant.robots.trunk import TRUNK
from pliant.robots.trunk_cube import floor, trunk_scene

# The Trunk's cables pull towards +y, -x, -y, +x (long cables 0-3, short ones 4-7).
CURL_DOWN_CABLE = 2


def cup_surface(
    *, radius: float = 20.0, height: float = 28.0, wall: float = 3.0, segments: int = 24
) -> tuple[np.ndarray, np.ndarray]:
    """A cup standing on y = 0, its axis along +y: the closed, outward-oriented surface of the
    solid swept by the profile (r, y): (0, 0), (R, 0), (R, H), (R - wall, H), (R - wall, wall),
    (0, wall) turned about the axis in `segments` steps. Returns (vertices, faces)."""
    _require_positive(radius=radius, height=height, wall=wall)
    if not (wall < radius and wall < height):
        raise ModelError(
            f"a {wall} mm wall leaves no inside to a cup of radius {radius} and height {height}"
        )
    _require_whole("segments", segments, 3)
    inner = radius - wall
    ring = [(radius, 0.0), (radius, height), (inner, height), (inner, wall)]
    angles = 2.0 * np.pi * np.arange(segments) / segments
    # Vertex 0: the bottom's centre; 1 + k * segments + j: ring point k at angle j; last: the
    # inside bottom's centre.
    vertices = [np.zeros(3)]
    for r, y in ring:
        vertices += [np.array([r * math.cos(a), y, r * math.sin(a)]) for a in angles]
    vertices.append(np.array([0.0, wall, 0.0]))
    j = np.arange(segments)
    nxt = (j + 1) % segments
    last = len(vertices) - 1
    faces = [np.column_stack([np.zeros(segments, dtype=np.int64), 1 + nxt, 1 + j])]
    for k in range(len(ring) - 1):
        a, b = 1 + k * segments, 1 + (k + 1) * segments
        faces.append(np.column_stack([a + j, a + nxt, b + nxt]))
        faces.append(np.column_stack([a + j, b + nxt, b + j]))
    top = 1 + (len(ring) - 1) * segments
    faces.append(np.column_stack([np.full(segments, last), top + j, top + nxt]))
    faces = np.vstack(faces)
    vertices = np.array(vertices)
    tri = vertices[faces]
    if np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum() < 0:
        faces = faces[:, ::-1]
    return vertices, faces


def solid_mass_properties(
    vertices: np.ndarray, faces: np.ndarray, mass: float
) -> tuple[np.ndarray, np.ndarray]:
    """Centre of mass and inertia about it of the uniform solid bounded by a closed,
    outward-oriented triangle mesh of total `mass`.

    Sums over the tetrahedra (0, a, b, c) of each face, with signed volume V = a.(b x c) / 6:
    the first moment V (a + b + c) / 4 and the second moment
    C = V / 20 (a a^T + b b^T + c c^T + s s^T), s = a + b + c (Tonon, J. Math. Stat. 1(1),
    2005); the inertia is trace(C) I - C, moved to the centre by the parallel axis theorem.
    """
    tri = np.asarray(vertices, dtype=float)[np.asarray(faces)]
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    volumes = np.einsum("ij,ij->i", a, np.cross(b, c)) / 6.0
    volume = volumes.sum()
    s = a + b + c
    centre = (volumes[:, None] * s).sum(axis=0) / (4.0 * volume)
    second = sum(np.einsum("k,ki,kj->ij", volumes, v, v) for v in (a, b, c, s)) / 20.0
    second *= mass / volume
    inertia = np.trace(second) * np.eye(3) - second
    inertia -= mass * (centre @ centre * np.eye(3) - np.outer(centre, centre))
    return centre, 0.5 * (inertia + inertia.T)


def demo_base_motion(t: float) -> float:
    """Hold the carriage while the trunk curls over the cup (0.5 s), then move it back by
    25 mm along the trunk's axis over 1 s."""
    return -25.0 * smooth_ramp(t, 0.5, 1.0)


@builder(Meshing(8.0), Solid(600.0, 0.3, mass="uniform"), *TRUNK[1:], Contact(0.3, 5.0))
def trunk_cup(
    p,
    *,
    cup_radius: float = 20.0,
    cup_height: float = 28.0,
    cup_wall: float = 3.0,
    cup_mass: float = 0.01,
    cup_position: tuple[float, float] = (0.0, 165.0),
    floor_height: float = -50.0,
    base_motion: Callable[[float], float] = demo_base_motion,
) -> Model:
    """The Trunk (SofaGym trunkcup-v0 material: E = 600 kPa, nu = 0.3; coarse mesh) over a floor
    y = floor_height, with a rigid cup of `cup_mass` kg standing on it, its axis at
    (x, z) = `cup_position`; the base moves along z by `base_motion(t)` (mm).

    The cup's rim (28 mm above the floor by default) stays under the trunk sagging under its
    own weight (its underside settles at y = -18.5 mm over the cup). `contact_margin` (mm):
    the trunk's points fall by up to 4.2 mm per 0.01 s step as it sags from straight.
    """
    _require_positive(cup_mass=cup_mass)

    def cup(body: TetBody) -> tuple[list[RigidBody], None]:
        vertices, faces = cup_surface(radius=cup_radius, height=cup_height, wall=cup_wall)
        centre, inertia = solid_mass_properties(vertices, faces, cup_mass)
        x, z = cup_position
        shape = TriangleMesh(vertices - centre, faces, position=centre + [x, floor_height, z])
        return [RigidBody(shape, cup_mass, inertia, friction=p.contact.friction, name="cup")], None

    # The Trunk, its cables and its carriage are trunk_cube's, with a cup for the cube.
    return trunk_scene(
        p,
        base_motion=base_motion,
        obstacle=floor(floor_height),
        objects=cup,
        name="trunk_cup",
    )


def demo_actuation(t: float) -> np.ndarray:
    """Pull the -y cable to 25 mm over 0.5 s and hold it: the distal end curls down over the
    cup's far wall and drags the cup back (20 mm by 0.4 s), and further as the carriage moves
    back (70 mm by 1.5 s, the cup tilting by 35 degrees on its near edge)."""
    values = np.zeros(8)
    values[CURL_DOWN_CABLE] = 25.0 * min(t / 0.5, 1.0)
    return values
