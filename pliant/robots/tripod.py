"""Tripod + Maze: three servo motors bend a soft tripod whose centre carries a rigid maze with a
ball rolling in it (SofaGym maze-v0, on SoftRobots' Tripod).

The tripod is a flat silicone star, a centre disc and three arms at 120 degrees, with a boss on
the centre (meshed with gmsh). The end of each arm is clamped in a servo horn (driven nodes)
that turns about a horizontal axis across the arm, `horn_length` mm further out: a positive
angle lifts the arm's end. Lifting and lowering the arms tilts the centre. The maze and the
ball of :mod:`pliant.robots.simple_maze` ride on it: the maze rests on four points of the boss'
top face, held by friction, so that the tripod carries its weight and the ball's (and the
contact problem stays well conditioned, see :mod:`pliant.robots.simple_maze`).
"""

from __future__ import annotations

import os
from collections.abc import Callable

import gmsh
import numpy as np

from pliant.constraints.base import EmbeddedPoints
from pliant.errors import ModelError
from pliant.fem.rigid import DrivenNodes, KinematicBody, servo
from pliant.geometry.collision import Box
from pliant.mesh.gmsh_session import gmsh_model, mesh_volumes, retry_meshing
from pliant.mesh.io import load_mesh
from pliant.mesh.shapes import _finish, _require_positive, require_arguments
from pliant.mesh.tetmesh import TetMesh
from pliant.model import Model
from pliant.robots.parameters import Meshing, Solid
from pliant.robots.scene import builder
from pliant.robots.simple_maze import GEL, checked_commands, demo_downhill, maze_model

N_SERVOS = 3


def arm_directions() -> np.ndarray:
    """(3, 2) unit directions of the arms in the xy plane: arm 0 along +y, then every 120
    degrees counter-clockwise."""
    angles = np.pi / 2 + 2 * np.pi / 3 * np.arange(N_SERVOS)
    return np.column_stack([np.cos(angles), np.sin(angles)])


@retry_meshing
def tripod_mesh(
    *,
    radius: float = 60.0,
    arm_width: float = 16.0,
    centre_radius: float = 22.0,
    thickness: float = 5.0,
    boss_radius: float = 14.0,
    boss_height: float = 8.0,
    clamp_length: float = 8.0,
    support_spread: float = 8.0,
    mesh_size: float = 5.0,
) -> TetMesh:
    """The tripod lying on z = 0: a disc of `centre_radius` and three arms of `arm_width`
    reaching `radius` along `arm_directions`, `thickness` thick, with a boss of `boss_radius`
    and `boss_height` on the centre.

    Landmarks: 'clamp' the box [[along, across, z] min, max] in each arm's frame (along the
    arm, across it, up) of the nodes its servo holds, the last `clamp_length` mm;
    'support_points' four points of the boss' top face at (+-support_spread, +-support_spread),
    where the maze rests.
    """
    require_arguments(
        locals(),
        "radius arm_width centre_radius thickness boss_radius boss_height clamp_length"
        " support_spread mesh_size",
    )
    if not (boss_radius <= centre_radius < radius - clamp_length and arm_width < 2 * centre_radius):
        raise ModelError(
            f"the tripod's parts do not fit: they need boss radius ({boss_radius}) <= centre"
            f" radius ({centre_radius}) < radius ({radius}) - clamp length ({clamp_length}) and"
            f" arm width ({arm_width}) < twice the centre radius"
        )
    if not np.sqrt(2.0) * support_spread < boss_radius:
        raise ModelError(
            f"the support points (+-{support_spread} mm) must lie on the boss (radius"
            f" {boss_radius} mm)"
        )
    with gmsh_model("tripod"):
        occ = gmsh.model.occ
        disc = occ.addCylinder(0.0, 0.0, 0.0, 0.0, 0.0, thickness, centre_radius)
        arms = []
        for dx, dy in arm_directions():
            arm = occ.addBox(0.0, -arm_width / 2, 0.0, radius, arm_width, thickness)
            occ.rotate([(3, arm)], 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, float(np.arctan2(dy, dx)))
            arms.append((3, arm))
        boss = occ.addCylinder(0.0, 0.0, thickness, 0.0, 0.0, boss_height, boss_radius)
        occ.fuse([(3, disc)], [*arms, (3, boss)])
        occ.removeAllDuplicates()
        points, tets = mesh_volumes(mesh_size)
    s, top = support_spread, thickness + boss_height
    landmarks = {
        "support_points": [[x, y, top] for x in (-s, s) for y in (-s, s)],
        "clamp": [
            [radius - clamp_length, -arm_width, -thickness],
            [radius + 1.0, arm_width, 2 * thickness],
        ],
    }
    return _finish(points, tets, landmarks)


def reference_tripod_mesh(
    path: str | os.PathLike, *, clamp_length: float = 8.0, support_spread: float = 8.0
) -> TetMesh:
    """SofaGym's Tripod mesh (maze-v0's Maze_tripod_coarse_04_test.vtk: y up, the arms in the
    xz plane along -90, 30 and 150 degrees), turned by Rot(x, 90 deg) into this module's frame:
    z up, lying on z = 0, arms along `arm_directions`; with the landmarks of `tripod_mesh`. It
    has no boss: the maze rests on its flat centre. For comparisons with the reference scene;
    Pliant's own tripod is `tripod_mesh`."""
    _require_positive(clamp_length=clamp_length, support_spread=support_spread)
    loaded = load_mesh(path)
    x, y, z = loaded.points.T
    points = np.column_stack([x, -z, y - y.min()])
    reach = float((points[:, :2] @ arm_directions().T).max())
    top, s = float(points[:, 2].max()), support_spread
    landmarks = {
        "support_points": [[a, b, top] for a in (-s, s) for b in (-s, s)],
        "clamp": [[reach - clamp_length, -reach / 2, -1.0], [reach + 1.0, reach / 2, top + 1.0]],
    }
    return _finish(points, loaded.tets, landmarks)


def clamped_nodes(mesh: TetMesh) -> list[np.ndarray]:
    """The nodes each servo holds: those inside the mesh's 'clamp' box in each arm's frame."""
    if "clamp" not in mesh.landmarks or "support_points" not in mesh.landmarks:
        raise ModelError("the tripod mesh needs the landmarks 'clamp' and 'support_points'")
    lo, hi = np.asarray(mesh.landmarks["clamp"], dtype=float)
    held = []
    for k, (dx, dy) in enumerate(arm_directions()):
        x, y, z = mesh.points.T
        local = np.column_stack([dx * x + dy * y, -dy * x + dx * y, z])
        inside = np.flatnonzero(np.all((local >= lo) & (local <= hi), axis=1))
        if inside.size == 0:
            raise ModelError(f"the clamp of servo {k} holds no node of the tripod mesh")
        held.append(inside)
    return held


def demo_servo_angles(t: float) -> np.ndarray:
    """Lower the arms towards the demo's downhill direction d and lift the others,
    a_k = -0.4 (u_k . d) rad (u_k the arm's direction): the maze tilts by about 0.2 rad and
    the ball rolls along the three corridors (`pliant.robots.simple_maze.DEMO_MOVES`)."""
    return -0.4 * arm_directions() @ demo_downhill(t)


@builder(Meshing(5.0), Solid(250.0, 0.45), *GEL)
def tripod_maze(
    p,
    *,
    horn_length: float = 10.0,
    max_servo_angle: float = 1.5,
    servo_angles: Callable[[float], np.ndarray] = demo_servo_angles,
) -> Model:
    """The tripod held by its three servos, the maze on its boss, the ball at the start of the
    maze's path.

    Args:
        mesh: replaces the tripod mesh (landmarks of `tripod_mesh`; arms along
            `arm_directions`, clamps held at z = their rest height).
        mesh_size: of the default `tripod_mesh`.
        young_modulus, poisson_ratio, density, material: the silicone (kPa, kg/mm^3).
        rayleigh_mass, rayleigh_stiffness: its damping.
        horn_length: distance (mm) from the centre of each clamp out to its servo's axis.
        max_servo_angle: range of each servo (rad, SofaGym's cap 1.5); an angle outside raises
            ConstraintError.
        maze_size, corridors, wall_thickness, wall_height, floor_thickness: the maze
            (:func:`pliant.robots.simple_maze.maze_boxes`).
        maze_mass, ball_radius, ball_mass: the rigid maze and ball (kg, mm).
        ball_friction: Coulomb coefficient of the ball on the maze.
        support_friction: of the maze on the boss, which holds it.
        contact_margin, contact_tolerance, contact_iterations: detection distance (mm), the
            contact solver's tolerance (mm) and its sweeps at most (a ball wedged in a corner
            takes a few thousand).
        servo_angles: the three servo angles (rad) as a function of time (s).
    """
    _require_positive(horn_length=horn_length, max_servo_angle=max_servo_angle)
    mesh = p.mesh_or(tripod_mesh)
    clamps = clamped_nodes(mesh)
    body = p.tet_body(mesh, fixed_nodes=np.concatenate(clamps))
    angles = checked_commands(servo_angles, N_SERVOS, max_servo_angle, "servo")
    drivers = []
    for k, (held, (dx, dy)) in enumerate(zip(clamps, arm_directions(), strict=True)):
        outwards = np.array([dx, dy, 0.0])
        clamp = mesh.points[held].mean(axis=0)
        horn = KinematicBody(
            Box([horn_length / 2, 2.0, 2.0], position=clamp + horn_length / 2 * outwards),
            servo(
                clamp + horn_length * outwards,
                np.cross([0.0, 0.0, 1.0], outwards),
                lambda t, k=k: angles(t)[k],
                clamp + horn_length / 2 * outwards,
            ),
            name=f"servo_{k}",
        )
        drivers.append(DrivenNodes(held, horn, name=f"servo_{k}"))
    supports = np.asarray(mesh.landmarks["support_points"], dtype=float)
    # The floor, below the lowest a horn can take an arm's end, catches a ball that falls out.
    floor = float(mesh.points[:, 2].min()) - horn_length - 30.0
    underside = float(supports[:, 2].max())
    points = EmbeddedPoints(mesh, supports)
    return maze_model(p, body, drivers, points, underside, floor, "tripod_maze")


def demo_actuation(t: float) -> np.ndarray:
    """No actuator: the servos follow the model's own scripted angles (`servo_angles`, by
    default `demo_servo_angles`)."""
    return np.zeros(0)
