"""The Diamond parallel robot, four cables (thesis §3.1.2, §5.1.3; SoftRobots tutorial)."""

from __future__ import annotations

import math

import numpy as np

from pliant.mesh import shapes
from pliant.model import Model
from pliant.robots.common import cables, effector, fixed_by_box, landmark
from pliant.robots.parameters import Cables, Damping, Gravity, Meshing, Solid, TotalMass
from pliant.robots.scene import builder

_ELBOWS = [(0.0, 97.0, 45.0), (-97.0, 0.0, 45.0), (0.0, -97.0, 45.0), (97.0, 0.0, 45.0)]
_PULLS = [(0.0, 10.0, 30.0), (-10.0, 0.0, 30.0), (0.0, -10.0, 30.0), (10.0, 0.0, 30.0)]


@builder(
    Meshing(13.0),
    Solid(180.0, 0.45, mass="uniform"),
    TotalMass(0.5),
    Gravity.Z,
    Damping(),
    Cables(),
)
def diamond(
    p,
    *,
    max_cable_displacement: float = 20.0,
) -> Model:
    """The Diamond: cables from pull points under the hub to the four elbows, effector on top.

    Defaults are the SoftRobots Diamond (E = 180 kPa, nu = 0.45, total mass 0.5 kg, cables
    at most 20 mm in inverse mode). `mesh` replaces Pliant's gmsh geometry, e.g. by the
    reference mesh placed in the scene frame; its landmarks default to the reference scene's.
    """
    mesh = p.mesh_or(shapes.diamond)
    box = landmark(mesh, "fixed_box", [[-15.0, -15.0, -40.0], [15.0, 15.0, 10.0]])
    body = p.tet_body(mesh, fixed_nodes=fixed_by_box(mesh, box))
    paths = [landmark(mesh, f"cable_points_{i}", _ELBOWS[i]) for i in range(4)]
    pulls = [landmark(mesh, f"pull_points_{i}", _PULLS[i])[0] for i in range(4)]
    acts = cables(mesh, body, paths, pulls, p.cables, max_cable_displacement)
    eff = effector(mesh, body, landmark(mesh, "effector", [0.0, 0.0, 125.0]))
    return Model(body, actuators=acts, effectors=[eff], name="diamond")


def demo_actuation(t: float) -> np.ndarray:
    """Pull each cable in turn to 10 mm and release it, one cable per second."""
    values = np.zeros(4)
    k = int(t) % 4
    values[k] = 10.0 * math.sin(math.pi * (t - int(t)))
    return values


def circle(n: int = 30, *, radius: float = 15.0, height: float = 115.0) -> np.ndarray:
    """The thesis' Diamond circle: n goals on a horizontal circle below the rest effector."""
    a = np.linspace(0.0, 2.0 * math.pi, n, endpoint=False)
    return np.column_stack([radius * np.cos(a), radius * np.sin(a), np.full(n, height)])


def lifted_circle(n: int = 30, *, radius: float = 15.0, height: float = 140.0) -> np.ndarray:
    """The circle above the rest effector that cables which only pull (0-30 mm, a learned
    condensed model's box) reach: pulling draws the elbows down and in and raises the top;
    the circle below it needs cables paying out below their rest length."""
    return circle(n, radius=radius, height=height)
