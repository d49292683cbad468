"""RodManipulator: two soft cable fingers turn a square rod lying on a table (thesis §4.2.2,
Fig. 4.8 B).

One deformable body: a plate with two cylindrical fingers hanging from it (meshed with gmsh),
over a rod lying along y on the table, one finger above each half of the rod. The plate is held
by a base that translates vertically (driven nodes). Four cables run down each finger, at
+x, +y, -x and -y near its surface: pulling one bends the finger towards that side. Their first
points lie in the plate, carried by the base with their motors. Pressed on the rod, the
fingertips hold it by friction; bending the two fingers in opposite x directions turns the rod
about the vertical, its ends dragged over the table.
"""

from __future__ import annotations

from collections.abc import Callable

import gmsh
import numpy as np

from pliant.constraints.contact import Contacts
from pliant.errors import ModelError
from pliant.fem.rigid import DrivenNodes, KinematicBody, RigidBody, rail
from pliant.geometry.collision import Box, Plane
from pliant.mesh.gmsh_session import gmsh_model, mesh_volumes, retry_meshing
from pliant.mesh.shapes import _finish, _require_positive, require_arguments
from pliant.mesh.tetmesh import TetMesh
from pliant.model import Model
from pliant.robots.common import cables, fingertips, fixed_by_box, smooth_ramp
from pliant.robots.parameters import Cables, Damping, Density, Gravity, Meshing, Solid
from pliant.robots.scene import builder

# Cable directions in each finger, in the order of the actuators: pulling cable k bends the
# finger towards DIRECTIONS[k].
DIRECTIONS = ("+x", "+y", "-x", "-y")
_OFFSETS = np.array([[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [0.0, -1.0]])


@retry_meshing
def fingers_mesh(
    *,
    spacing: float = 50.0,
    finger_length: float = 50.0,
    finger_radius: float = 6.0,
    plate_thickness: float = 6.0,
    cable_inset: float = 2.0,
    mesh_size: float = 4.0,
) -> TetMesh:
    """A plate z in [finger_length, finger_length + plate_thickness] with two fingers hanging
    down to z = 0, their axes at (0, +-spacing / 2).

    Landmarks: 'fixed_box' (the plate), 'cable_points_<f>_<k>' (finger f = 0 at y < 0, 1 at
    y > 0; cable k pulls towards DIRECTIONS[k], `cable_inset` mm inside the surface, from the
    plate down to the tip), 'effector_<f>' (the centres of the fingertips).
    """
    require_arguments(
        locals(), "spacing finger_length finger_radius plate_thickness cable_inset mesh_size"
    )
    if not (spacing > 2 * finger_radius and cable_inset < finger_radius):
        raise ModelError(
            f"the fingers (radius {finger_radius}) must not overlap (spacing {spacing}) and the"
            f" cables must lie inside them (inset {cable_inset})"
        )
    half_x = 2 * finger_radius
    half_y = spacing / 2 + 2 * finger_radius
    top = finger_length + plate_thickness
    centres = [(0.0, side * spacing / 2) for side in (-1.0, 1.0)]
    with gmsh_model("rod_manipulator"):
        occ = gmsh.model.occ
        plate = occ.addBox(-half_x, -half_y, finger_length, 2 * half_x, 2 * half_y, plate_thickness)
        fingers = [
            occ.addCylinder(x, y, 0.0, 0.0, 0.0, finger_length, finger_radius) for x, y in centres
        ]
        occ.fuse([(3, plate)], [(3, f) for f in fingers])
        points, tets = mesh_volumes(mesh_size)
    z = np.linspace(finger_length + plate_thickness / 2, cable_inset, 10)
    landmarks = {
        "fixed_box": np.array(
            [[-half_x - 1, -half_y - 1, finger_length + 1e-6], [half_x + 1, half_y + 1, top + 1]]
        ),
    }
    arm = finger_radius - cable_inset
    for f, (x, y) in enumerate(centres):
        landmarks[f"effector_{f}"] = [x, y, 0.0]
        for k, (dx, dy) in enumerate(_OFFSETS):
            landmarks[f"cable_points_{f}_{k}"] = np.column_stack(
                [np.full(z.size, x + arm * dx), np.full(z.size, y + arm * dy), z]
            )
    return _finish(points, tets, landmarks)


def demo_base_motion(t: float) -> float:
    """Lower the fingers by 7 mm in 0.15 s: from 5 mm above the rod to pressing 2 mm on it."""
    return -7.0 * smooth_ramp(t, 0.0, 0.15)


@builder(Meshing(4.0), Solid(500.0, 0.45), Density(), Gravity.Z, Damping(1.0, 0.05), Cables())
def rod_manipulator(
    p,
    *,
    spacing: float = 50.0,
    finger_length: float = 50.0,
    max_cable_displacement: float = 15.0,
    rod_size: tuple[float, float, float] = (10.0, 80.0, 10.0),
    rod_mass: float = 0.008,
    clearance: float = 5.0,
    finger_friction: float = 1.0,
    table_friction: float = 0.3,
    contact_margin: float = 2.0,
    base_motion: Callable[[float], float] = demo_base_motion,
) -> Model:
    """The two fingers on their base, moved along z by `base_motion(t)` (mm), over the rod.

    Args:
        mesh: replaces the fingers' mesh (`fingers_mesh` landmarks, tips on z = 0).
        spacing, finger_length, mesh_size: of the default `fingers_mesh`.
        young_modulus, poisson_ratio, density, material: the fingers' silicone (kPa, kg/mm^3).
        max_cable_displacement: bound of each of the 8 cables (mm); actuators in the order
            finger 0's DIRECTIONS, then finger 1's.
        rod_size: the rod's (x, y, z) size (mm); it lies along y, centred under the fingers.
        rod_mass: its mass (kg).
        clearance: gap between the fingertips and the rod's top at the start (mm).
        finger_friction, table_friction: Coulomb coefficients of the fingers on the rod and of
            the rod on the table.
        contact_margin: detection distance (mm) of the fingers' surface nodes.
        base_motion: the base's displacement along z (mm) as a function of time (s).
    """
    _require_positive(
        rod_x=rod_size[0],
        rod_y=rod_size[1],
        rod_z=rod_size[2],
        rod_mass=rod_mass,
        clearance=clearance,
        finger_friction=finger_friction,
    )
    mesh = p.mesh_or(fingers_mesh, spacing=spacing, finger_length=finger_length)
    plate = fixed_by_box(mesh, mesh.landmarks["fixed_box"])
    body = p.tet_body(mesh, fixed_nodes=plate)
    acts = cables(
        mesh,
        body,
        [mesh.landmarks[f"cable_points_{f}_{k}"] for f in range(2) for k in range(4)],
        [None] * 8,
        p.cables,
        max_cable_displacement,
        names=[f"cable_{f}_{direction}" for f in range(2) for direction in DIRECTIONS],
    )
    tips = fingertips(mesh, body, [mesh.landmarks[f"effector_{f}"] for f in range(2)])
    half = np.asarray(rod_size, dtype=float) / 2
    rod_bottom = float(mesh.points[:, 2].min()) - clearance - rod_size[2]
    top = float(mesh.points[:, 2].max())
    base = KinematicBody(
        Box([spacing / 2, spacing, 2.0], position=[0.0, 0.0, top + 2.0]),
        rail([0.0, 0.0, top + 2.0], [0.0, 0.0, 1.0], base_motion),
        name="base",
    )
    rod = RigidBody(
        Box(half, position=[0.0, 0.0, rod_bottom + half[2]]),
        rod_mass,
        friction=finger_friction,
        name="rod",
    )
    table = Plane(point=(0.0, 0.0, rod_bottom))
    # The body's points on the rod take the rod's coefficient; the rod on the table takes
    # sqrt(mu_rod mu_table) (pliant.constraints.contact), hence the table's value.
    table_mu = table_friction**2 / finger_friction
    return Model(
        body,
        actuators=acts,
        effectors=tips,
        contacts=Contacts([table], friction=table_mu, margin=contact_margin),
        drivers=[DrivenNodes(plate, base, name="base")],
        rigid_bodies=[rod],
        name="rod_manipulator",
    )


def rod_angle(rotation: np.ndarray) -> float:
    """The rod's turn about the vertical (rad): the angle of its long axis (body y) in the
    table's plane from the world y axis."""
    axis = np.asarray(rotation)[:, 1]
    return float(np.arctan2(-axis[0], axis[1]))


def demo_actuation(t: float, *, pull: float = 8.0) -> np.ndarray:
    """Once the fingers press on the rod (0.15 s), bend finger 0 (y < 0) towards +x and finger 1
    towards -x, pulling their cables to `pull` mm over 0.5 s: the rod turns counter-clockwise
    seen from above."""
    values = np.zeros(8)
    amount = pull * min(max((t - 0.15) / 0.5, 0.0), 1.0)
    values[DIRECTIONS.index("+x")] = amount
    values[4 + DIRECTIONS.index("-x")] = amount
    return values
