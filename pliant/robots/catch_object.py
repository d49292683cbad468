"""CatchTheObject: a pneumatic gripper on a cart catches a falling ball (SofaGym
catchtheobject-v0).

One deformable body, a U open upwards (meshed with gmsh): a palm held by the cart, which
translates along x on its rail (driven nodes), and two PneuNet fingers standing on its ends:
sealed chambers in blocks on each finger's outer side, a stiffer spine (the strain-limiting
layer) along its inner face, so that inflating the chambers lengthens the outer side only and
bends the fingers inwards; one pressure drives all chambers. A rigid ball falls from above,
beside the gripper; the cart has to be under it when it arrives.
"""

from __future__ import annotations

from collections.abc import Callable

import gmsh
import numpy as np

from pliant.errors import ModelError
from pliant.fem.body import TetBody
from pliant.fem.rigid import DrivenNodes, KinematicBody, RigidBody, rail
from pliant.geometry.collision import Box, Plane, Sphere
from pliant.mesh.gmsh_session import gmsh_model, retry_meshing
from pliant.mesh.shapes import _finish, _hollowed, _require_positive, require_arguments
from pliant.mesh.tetmesh import TetMesh
from pliant.model import Model
from pliant.robots.common import cavity, fingertips, fixed_by_box, smooth_ramp
from pliant.robots.parameters import Ball, Contact, Damping, Density, Gravity, Meshing, Solid
from pliant.robots.scene import builder


@retry_meshing
def catcher_mesh(
    *,
    opening: float = 30.0,
    finger_length: float = 40.0,
    finger_thickness: float = 18.0,
    width: float = 24.0,
    palm_thickness: float = 8.0,
    spine_thickness: float = 2.0,
    n_chambers: int = 4,
    gap: float = 2.0,
    wall: float = 2.0,
    mesh_size: float = 4.0,
) -> TetMesh:
    """The U-shaped gripper: a palm z in [0, palm_thickness] and two PneuNet fingers standing
    on its ends up to palm_thickness + finger_length, their inner faces at x = +-opening / 2,
    centred on y = 0.

    A finger is a spine `spine_thickness` thick along its inner face carrying, on its outer
    side, `n_chambers` blocks separated by slits `gap` wide; each block holds a sealed box
    chamber with walls `wall` thick. Inflated, the chambers push their neighbours apart and
    bend the finger towards its spine, inwards.

    Surfaces: 'cavity_0..' (the chambers, left finger first, oriented out of the air) and
    'cavity' (all of them). Landmarks: 'fixed_box' (the palm's central third), 'effector_0/1'
    (the fingertips' inner edges).
    """
    require_arguments(
        locals(),
        "opening finger_length finger_thickness width palm_thickness spine_thickness gap wall"
        " mesh_size",
        n_chambers=1,
    )
    block = (finger_length - (n_chambers - 1) * gap) / n_chambers
    depth = finger_thickness - spine_thickness - wall
    if not (block > 2 * wall and depth > 0 and width > 2 * wall):
        raise ModelError(
            f"{n_chambers} chambers with {wall} mm walls do not fit in a {finger_length} x"
            f" {finger_thickness} x {width} mm finger with a {spine_thickness} mm spine"
        )
    outer = opening / 2 + finger_thickness
    top = palm_thickness + finger_length
    floors = [palm_thickness + k * (block + gap) for k in range(n_chambers)]
    # The chamber's x range, from the spine to the outer wall, on the left then right finger.
    sides = [
        (-outer + wall, -opening / 2 - spine_thickness),
        (opening / 2 + spine_thickness, outer - wall),
    ]
    chambers = [
        (
            np.array([lo, -width / 2 + wall, z + wall]),
            np.array([hi, width / 2 - wall, z + block - wall]),
        )
        for lo, hi in sides
        for z in floors
    ]
    with gmsh_model("catch_object"):
        occ = gmsh.model.occ
        parts = [occ.addBox(-outer, -width / 2, 0.0, 2 * outer, width, palm_thickness)]
        # Each finger: its spine, then its blocks overlapping the spine by 1 mm so that the
        # fusion joins them (left finger, then right).
        for spine_x, block_x in (
            (-opening / 2 - spine_thickness, -outer),
            (opening / 2, opening / 2 + spine_thickness - 1.0),
        ):
            parts.append(
                occ.addBox(
                    spine_x, -width / 2, palm_thickness, spine_thickness, width, finger_length
                )
            )
            parts += [
                occ.addBox(block_x, -width / 2, z, depth + wall + 1.0, width, block) for z in floors
            ]
        points, tets, surfaces = _hollowed(parts, chambers, mesh_size, 1e-6 * outer)
    landmarks = {
        "fixed_box": np.array([[-outer / 3, -width, -1.0], [outer / 3, width, palm_thickness / 2]]),
        "effector_0": [-opening / 2, 0.0, top],
        "effector_1": [opening / 2, 0.0, top],
    }
    return _finish(points, tets, landmarks, surfaces)


def demo_cart_motion(t: float) -> float:
    """Slide the cart 20 mm along +x (under the ball) in 0.12 s, a smooth ramp."""
    return 20.0 * smooth_ramp(t, 0.0, 0.12)


@builder(
    Meshing(4.0),
    Solid(500.0, 0.3),
    Density(),
    Gravity.Z,
    Damping(1.0, 0.05),
    Contact(0.6),
    Ball(10.0, 0.003),
)
def catch_object(
    p,
    *,
    opening: float = 30.0,
    finger_length: float = 40.0,
    palm_thickness: float = 8.0,
    spine_thickness: float = 2.0,
    layer_stiffness: float = 5.0,
    max_pressure: float = 60.0,
    ball_position: tuple[float, float, float] = (20.0, 0.0, 100.0),
    cart_motion: Callable[[float], float] = demo_cart_motion,
) -> Model:
    """The gripper (`catcher_mesh`) on its cart, moved along x by `cart_motion(t)` (mm), under
    a ball released at rest at `ball_position`; a floor 5 mm under the palm (the cart's top).

    Args:
        mesh: replaces the gripper mesh (palm on z = 0, surface 'cavity', landmarks
            'fixed_box' and 'effector_0/1'); it must match `opening` and `palm_thickness`.
        opening, finger_length, palm_thickness, mesh_size: of the default `catcher_mesh`.
        young_modulus, poisson_ratio, density, material: the silicone (kPa, kg/mm^3). SofaGym's
            gripper is a 10 mm pad with E = 3e4; this one is a 50 mm hand of softer silicone.
        spine_thickness, layer_stiffness: the fingers' spines (their elements within
            `spine_thickness` mm of the inner faces) are `layer_stiffness` times stiffer: the
            strain-limiting layer that makes an inflated finger bend instead of stretching.
        max_pressure: upper bound of the chambers' pressure (kPa); one actuator inflates both.
        ball_radius, ball_mass, ball_position: the rigid ball (mm, kg), released at rest.
        friction: Coulomb coefficient of the ball, the fingers and the floor.
        contact_margin: detection distance (mm) of the gripper's surface nodes; they travel up
            to 2.6 mm per 0.01 s step with the demo's cart.
        cart_motion: the cart's displacement along x (mm) as a function of time (s).
    """
    ball_radius, ball_mass = p.ball.ball_radius, p.ball.ball_mass
    _require_positive(
        spine_thickness=spine_thickness,
        layer_stiffness=layer_stiffness,
        ball_radius=ball_radius,
        ball_mass=ball_mass,
    )
    mesh = p.mesh_or(
        catcher_mesh,
        opening=opening,
        finger_length=finger_length,
        palm_thickness=palm_thickness,
        spine_thickness=spine_thickness,
    )
    if "cavity" not in mesh.surfaces:
        raise ModelError("the gripper mesh has no 'cavity' surface (the chambers' walls)")
    palm = fixed_by_box(mesh, mesh.landmarks["fixed_box"])
    body = p.tet_body(mesh, fixed_nodes=palm)
    _stiffen_inner_layers(
        body,
        opening=opening,
        palm_thickness=palm_thickness,
        thickness=spine_thickness,
        factor=layer_stiffness,
    )
    chambers = cavity(mesh, body, "cavity", name="chambers", max_pressure=max_pressure)
    tips = fingertips(mesh, body, [mesh.landmarks[f"effector_{i}"] for i in range(2)])
    bottom = float(mesh.points[:, 2].min())
    cart = KinematicBody(
        Box([35.0, 15.0, 2.5], position=[0.0, 0.0, bottom - 2.5]),
        rail([0.0, 0.0, bottom - 2.5], [1.0, 0.0, 0.0], cart_motion),
        name="cart",
    )
    ball = RigidBody(
        Sphere(ball_radius, position=ball_position),
        ball_mass,
        friction=p.contact.friction,
        name="ball",
    )
    floor = Plane(point=(0.0, 0.0, bottom - 5.0))
    return Model(
        body,
        actuators=[chambers],
        effectors=tips,
        contacts=p.contacts([floor]),
        drivers=[DrivenNodes(palm, cart, name="cart")],
        rigid_bodies=[ball],
        name="catch_object",
    )


def _stiffen_inner_layers(
    body: TetBody, *, opening: float, palm_thickness: float, thickness: float, factor: float
) -> None:
    """Multiply the Lame coefficients of the fingers' elements within `thickness` of their
    inner faces (x = +-opening / 2, above the palm) by `factor`."""
    centres = body.mesh.points[body.mesh.tets].mean(axis=1)
    x = np.abs(centres[:, 0])
    layer = (centres[:, 2] > palm_thickness) & (x < opening / 2 + thickness)
    body.mu[layer] *= factor
    body.lam[layer] *= factor


def demo_actuation(t: float) -> np.ndarray:
    """Wait for the ball to land (0.25 s), then inflate the chambers to 30 kPa over 0.35 s and
    hold: the fingertips close over the ball, nearer to each other than its diameter."""
    return np.array([30.0 * min(max((t - 0.25) / 0.35, 0.0), 1.0)])
