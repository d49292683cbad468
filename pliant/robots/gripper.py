"""The Soft Gripper: two cable fingers on a translating base, and a rigid cube on the floor
(thesis §3.1.2, §3.2.1; SofaGym gripper-v0).

One deformable body, a palm with two fingers hanging from its ends (a U, meshed with gmsh);
the palm is held by the base, which translates (driven nodes). A cable runs down the inner
side of each finger from the palm to the fingertip: pulling it shortens that side and closes
the finger. Its first point lies in the palm, so that it is carried by the base like the
cable's motor. The cube is a rigid body resting on the floor; the fingers grasp it by
frictional contact and the base lifts it.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import gmsh
import numpy as np

from pliant.errors import ModelError
from pliant.fem.rigid import DrivenNodes, KinematicBody, RigidBody, Trajectory
from pliant.geometry.collision import Box, Plane
from pliant.mesh.gmsh_session import gmsh_model, mesh_volumes, retry_meshing
from pliant.mesh.tetmesh import TetMesh
from pliant.model import Model
from pliant.robots.common import cables, fingertips, fixed_by_box, landmark, smooth_ramp
from pliant.robots.parameters import (
    Cables,
    Contact,
    Cube,
    Damping,
    Density,
    Gravity,
    Meshing,
    Solid,
)
from pliant.robots.scene import builder


@retry_meshing
def gripper_mesh(
    *,
    opening: float = 40.0,
    finger_length: float = 60.0,
    finger_thickness: float = 10.0,
    width: float = 20.0,
    palm_thickness: float = 10.0,
    cable_inset: float = 2.0,
    mesh_size: float = 5.0,
) -> TetMesh:
    """The U-shaped body: a palm on top (z in [finger_length, + palm_thickness]) and two fingers
    down to z = 0, their inner faces at x = +-opening / 2, centred on y = 0.

    Landmarks: 'fixed_box' (the palm), 'cable_points_0/1' (the left and right fingers' cables,
    from the palm down their inner sides), 'effector_0/1' (the fingertips).
    """
    for name, value in (
        ("opening", opening),
        ("finger_length", finger_length),
        ("finger_thickness", finger_thickness),
        ("width", width),
        ("palm_thickness", palm_thickness),
        ("mesh_size", mesh_size),
    ):
        if not (math.isfinite(value) and value > 0):
            raise ModelError(f"{name} must be a positive finite number, got {value!r}")
    if not 0 < cable_inset < finger_thickness / 2:
        raise ModelError(f"cable_inset must lie in (0, {finger_thickness / 2}), got {cable_inset}")
    outer = opening / 2 + finger_thickness
    with gmsh_model("gripper"):
        occ = gmsh.model.occ
        palm = occ.addBox(-outer, -width / 2, finger_length, 2 * outer, width, palm_thickness)
        fingers = [
            occ.addBox(x, -width / 2, 0.0, finger_thickness, width, finger_length)
            for x in (-outer, opening / 2)
        ]
        occ.fuse([(3, palm)], [(3, f) for f in fingers])
        points, tets = mesh_volumes(mesh_size)
    top = finger_length + palm_thickness
    z = np.linspace(finger_length + palm_thickness / 2, cable_inset, 8)
    landmarks = {
        "fixed_box": np.array(
            [[-outer - 1, -width, finger_length + 1e-6], [outer + 1, width, top + 1]]
        ),
    }
    for i, side in enumerate((-1.0, 1.0)):
        x = side * (opening / 2 + cable_inset)
        landmarks[f"cable_points_{i}"] = np.column_stack([np.full(8, x), np.zeros(8), z])
        landmarks[f"effector_{i}"] = np.array(
            [[side * (opening / 2 + finger_thickness / 2), 0.0, 0.0]]
        )
    return TetMesh(points, tets, landmarks=landmarks)


def demo_base_motion(t: float) -> float:
    """Hold the base while the fingers close (1.5 s), then lift by 20 mm over 1.5 s."""
    return 20.0 * smooth_ramp(t, 1.5, 1.5)


@builder(
    Meshing(5.0),
    Solid(20000.0, 0.48),
    Density(),
    Gravity.Z,
    Damping(1.0, 0.01),
    Cables(),
    Contact(0.8, contact_margin=1.0),
    Cube(20.0, 0.01),
)
def soft_gripper(
    p,
    *,
    max_cable_displacement: float = 10.0,
    floor_height: float = -10.0,
    base_motion: Callable[[float], float | np.ndarray] = demo_base_motion,
) -> Model:
    """Two cable fingers on a base translated by `base_motion(t)` (mm), over a cube:
    a number moves it along z, a 3-vector translates it along any axis (the thesis' base).

    Defaults: SofaGym's gripper fingers (E = 20000 kPa, nu = 0.48), silicone density; a 20 mm,
    10 g cube on the floor 10 mm under the fingertips, centred between the fingers (10 mm
    from each); friction 0.8 for the fingers, the cube and the floor.
    """
    mesh = p.mesh_or(gripper_mesh)
    palm = fixed_by_box(mesh, landmark(mesh, "fixed_box", [[-31, -11, 60], [31, 11, 71]]))
    body = p.tet_body(mesh, fixed_nodes=palm)
    paths = [landmark(mesh, f"cable_points_{i}", [[0.0, 0.0, 0.0]]) for i in range(2)]
    fingers = cables(mesh, body, paths, [None, None], p.cables, max_cable_displacement)
    ends = [landmark(mesh, f"effector_{i}", [[0.0, 0.0, 0.0]]) for i in range(2)]
    tips = fingertips(mesh, body, ends)
    base = KinematicBody(
        Box([35.0, 12.0, 3.0], position=[0.0, 0.0, 73.0]),
        _translation([0.0, 0.0, 73.0], base_motion),
        name="base",
    )
    half = p.cube.cube_size / 2
    cube = RigidBody(
        Box([half, half, half], position=[0.0, 0.0, floor_height + half]),
        p.cube.cube_mass,
        friction=p.contact.friction,
        name="cube",
    )
    contacts = p.contacts([Plane(point=(0.0, 0.0, floor_height))])
    return Model(
        body,
        actuators=fingers,
        effectors=tips,
        contacts=contacts,
        drivers=[DrivenNodes(palm, base, name="base")],
        rigid_bodies=[cube],
        name="soft_gripper",
    )


def _translation(origin, motion: Callable[[float], float | np.ndarray]) -> Trajectory:
    """The base's pose: origin + motion(t), along z for a number; never turned."""
    o = np.asarray(origin, dtype=float)

    def pose(t: float) -> tuple[np.ndarray, np.ndarray]:
        d = np.asarray(motion(t), dtype=float)
        if d.ndim == 0:
            return o + [0.0, 0.0, float(d)], np.eye(3)
        return o + d.reshape(3), np.eye(3)

    return pose


def demo_actuation(t: float) -> np.ndarray:
    """Close both fingers (cables to 4.5 mm over 1 s) and keep them closed; the base lifts by
    its own scripted motion."""
    return np.full(2, 4.5 * min(t, 1.0))
