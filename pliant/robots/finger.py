"""The parametric Soft Finger, two cables (thesis §5.1.3, §5.1.6)."""

from __future__ import annotations

import math

import numpy as np

from pliant.mesh import shapes
from pliant.mesh.shapes import FingerResolution
from pliant.model import Model
from pliant.robots.common import cables, curling, effector, fixed_by_box
from pliant.robots.parameters import Cables, Damping, Density, Gravity, Meshed, Solid
from pliant.robots.scene import builder


@builder(Meshed(), Solid(3000.0, 0.47), Density(), Gravity.Z, Damping(), Cables())
def soft_finger(
    p,
    *,
    length: float = 40.0,
    height: float = 20.0,
    joint_height: float = 6.0,
    resolution: FingerResolution = "coarse",
    max_cable_displacement: float = 20.0,
) -> Model:
    """The Soft Finger: three phalanges along +x from a fixed base, cable 0 closes it (-z).

    Design parameters Length, Height and Joint Height (38-42, 20-22, 5-8 mm) rebuild the
    geometry; `resolution` picks the thesis' three meshes (~1.5k, ~9k, ~18k tetrahedra).
    Material defaults: E = 3000 kPa, nu = 0.47 (thesis §5.1.6), silicone density.
    """
    mesh = p.mesh_or(
        shapes.soft_finger,
        length=length,
        height=height,
        joint_height=joint_height,
        resolution=resolution,
    )
    body = p.tet_body(mesh, fixed_nodes=fixed_by_box(mesh, mesh.landmarks["fixed_box"]))
    paths = [mesh.landmarks[f"cable_points_{i}"] for i in range(2)]
    pulls = [mesh.landmarks[f"pull_points_{i}"][0] for i in range(2)]
    acts = cables(mesh, body, paths, pulls, p.cables, max_cable_displacement)
    eff = effector(mesh, body, mesh.landmarks["effector"])
    return Model(body, actuators=acts, effectors=[eff], name="finger")


def demo_actuation(t: float) -> np.ndarray:
    """Close the finger with cable 0 up to 8 mm, open it, then bend it up with cable 1."""
    phase = t % 3.0
    if phase < 2.0:
        return np.array([8.0 * math.sin(math.pi * phase / 2.0), 0.0])
    return np.array([0.0, 4.0 * math.sin(math.pi * (phase - 2.0))])


def closing(
    n: int = 25, *, tip: tuple[float, float, float] = (143.0, 0.0, 10.0), drop: float = 30.0
) -> np.ndarray:
    """The thesis' closing trajectory: n goals along an arc as the fingertip curls down."""
    return curling(n, tip, drop, 0.25)
