"""CartStemContact: a vertical beam on a cart between two obstacles (thesis §3.1.2, §3.3.2,
§4.2.2; SofaGym cartstemcontact-v0).

The cart translates along x and carries the beam's base (driven nodes); two boxes, one on
each side and above the cart, stop the beam. The beam is a tetrahedral bar, or a Cosserat rod
of square section (`stem="rod"`, SofaGym's stem is a Cosserat beam). The task is to bring the
tip to an abscissa behind an obstacle: moving the cart towards that obstacle presses the
beam on it and swings the tip back, away from the goal (the local minimum of a QP started
without contact); the tip gets there only by first bending the beam over the opposite
obstacle (Fig. 3.11).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from functools import partial
from typing import Literal

import numpy as np

from pliant.constraints.base import EmbeddedPoints
from pliant.constraints.effector import PositionEffector
from pliant.errors import ModelError
from pliant.fem.rigid import DrivenNodes, KinematicBody, rail
from pliant.fem.rod import ClampedEnd, RodSection
from pliant.geometry.collision import Box
from pliant.mesh import box_beam
from pliant.mesh.tetmesh import TetMesh
from pliant.model import Model
from pliant.robots.common import effector, fixed_by_box, landmark, smooth_ramp
from pliant.robots.parameters import Contact, Damping, Density, Gravity, Meshed, Solid
from pliant.robots.scene import builder, variant

# How far the cart slides left in the scripted solution: the tetrahedral bar (2 cells across)
# is stiffer in bending than the rod (linear tetrahedra lock), so it needs a longer slide.
DEMO_SLIDE = {"tetrahedra": 24.0, "rod": 20.0}


def demo_cart_motion(t: float, stem: str = "tetrahedra") -> float:
    """The scripted solution for a goal behind the right obstacle (tip at x = 25 mm): the cart
    slides left (a smooth 2 s ramp), bending the beam over the left obstacle so that its tip
    swings right, over the right one."""
    return -DEMO_SLIDE[stem] * smooth_ramp(t, 0.0, 2.0)


def stem_mesh(length: float, width: float, cells: int) -> TetMesh:
    """A vertical square beam standing on z = 0, centred on the z axis: `cells` hexahedra along
    it, 2 x 2 across, 6 tetrahedra each (box_beam turned from +x to +z)."""
    beam = box_beam(length, width, width, nx=cells, ny=2, nz=2)
    # (x, y, z) -> (y, z, x) is a cyclic permutation: orientations are kept.
    points = beam.points[:, [1, 2, 0]] - [width / 2, width / 2, 0.0]
    half = width / 2 + 1e-3 * width
    landmarks = {
        "fixed_box": np.array([[-half, -half, -1e-3 * width], [half, half, 1e-3 * width]]),
        "effector": np.array([[0.0, 0.0, length]]),
    }
    return TetMesh(points, beam.tets, landmarks=landmarks)


@builder(
    Meshed(), Solid(2000.0, 0.3), Density(1.0e-6), Gravity.Z, Damping(1.0, 0.01), Contact(0.0, 3.0)
)
def cartstem_contact(
    p,
    *,
    stem: Literal["rod", "tetrahedra"] = "tetrahedra",
    length: float = 100.0,
    width: float = 10.0,
    cells: int = 10,
    obstacle_spacing: float = 40.0,
    obstacle_size: tuple[float, float, float] = (10.0, 20.0, 20.0),
    obstacle_height: float = 10.0,
    obstacles: bool = True,
    cart_motion: Callable[[float], float] | None = None,
) -> Model:
    """The beam on its cart between the two obstacles (or alone, `obstacles=False`).

    Args:
        stem: "tetrahedra" (a bar of 6-tet cells, 2 x 2 across) or "rod" (a Cosserat rod of
            `2 cells` elements, its nodes colliding as balls of radius width / 2).
        mesh: replaces the beam mesh (vertical, base on z = 0; tetrahedral stem only).
        length, width, cells: the beam (mm), square section, cells along it.
        young_modulus, poisson_ratio, density, material: the beam's material (kPa, kg/mm^3).
        rayleigh_mass, rayleigh_stiffness: damping of the beam.
        obstacle_spacing: distance between the obstacles' inner faces, centred on x = 0.
        obstacle_size: (x, y, z) size of each box obstacle.
        obstacle_height: height of the obstacles' lower faces above the cart.
        friction: Coulomb coefficient of the beam on the obstacles.
        contact_margin: detection distance (mm); the beam's points move up to about 1 mm per
            0.01 s step (2 mm at most in the tests) when the cart drags it over an obstacle.
        obstacles: False leaves the obstacles out: the stem alone on its cart (CartStem).
        cart_motion: the cart's displacement along x (mm) as a function of time (s); default
            the scripted solution for the stem (`demo_cart_motion`).
    """
    if not (math.isfinite(obstacle_spacing) and obstacle_spacing > width):
        raise ModelError(
            f"the obstacles must be further apart than the beam is wide ({width} mm), got"
            f" obstacle_spacing={obstacle_spacing!r}"
        )
    if stem not in DEMO_SLIDE:
        raise ModelError(f"stem must be 'rod' or 'tetrahedra', got {stem!r}")
    if cart_motion is None:
        cart_motion = partial(demo_cart_motion, stem=stem)
    half = np.asarray(obstacle_size, dtype=float) / 2
    centre_z = obstacle_height + half[2]
    boxes = [
        Box(half, position=[side * (obstacle_spacing / 2 + half[0]), 0.0, centre_z])
        for side in (-1.0, 1.0)
    ]
    cart = KinematicBody(
        Box([2.0 * width, width, 2.0], position=[0.0, 0.0, -2.0]),
        rail([0.0, 0.0, -2.0], [1.0, 0.0, 0.0], cart_motion),
        name="cart",
    )
    if stem == "rod":
        if p.mesh is not None:
            raise ModelError("a mesh replaces the tetrahedral stem only (stem='tetrahedra')")
        n = 2 * cells
        rod = p.rod_body(
            np.column_stack([np.zeros(n + 1), np.zeros(n + 1), np.linspace(0.0, length, n + 1)]),
            RodSection.rectangle(width, width),
            normal=(1.0, 0.0, 0.0),
            clamped=[0],
        )
        return Model(
            rod,
            effectors=[PositionEffector(EmbeddedPoints.at_nodes([n]), rod.rest_positions)],
            contacts=p.contacts(boxes, thickness=0.5 * width) if obstacles else None,
            drivers=[ClampedEnd(rod, 0, cart, name="cart")],
            name="cartstem_contact",
        )
    mesh = p.mesh if p.mesh is not None else stem_mesh(length, width, cells)
    base = fixed_by_box(mesh, landmark(mesh, "fixed_box", [[-width, -width, -0.01], [width] * 3]))
    body = p.tet_body(mesh, fixed_nodes=base)
    tip = effector(mesh, body, landmark(mesh, "effector", [0.0, 0.0, length]))
    return Model(
        body,
        effectors=[tip],
        contacts=p.contacts(boxes) if obstacles else None,
        drivers=[DrivenNodes(base, cart, name="cart")],
        name="cartstem_contact",
    )


def demo_actuation(t: float) -> np.ndarray:
    """No actuator: the cart follows the model's own scripted motion (`cart_motion`)."""
    return np.zeros(0)


def stem_demo_cart_motion(t: float) -> float:
    """Shake the cart: 10 mm at 2 Hz for a second, then hold it (the stem swings and settles)."""
    return 10.0 * math.sin(4.0 * math.pi * min(t, 1.0))


cartstem = variant(
    cartstem_contact,
    "cartstem",
    """CartStem (SofaGym cartstem-v0): the stem alone on its cart, no obstacle; a Cosserat rod
    by default, as SofaGym's (keywords of :func:`cartstem_contact`).""",
    stem="rod",
    young_modulus=1000.0,
    obstacles=False,
    cart_motion=stem_demo_cart_motion,
)

cartstem_rod = variant(
    cartstem_contact,
    "cartstem_rod",
    """CartStemContact with a Cosserat rod stem (keywords of :func:`cartstem_contact`).""",
    stem="rod",
)
