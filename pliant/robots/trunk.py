"""The cable Trunk, eight cables (thesis §3.1.2; SofaGym trunk-v0)."""

from __future__ import annotations

import math

import numpy as np

from pliant.mesh import shapes
from pliant.model import Model
from pliant.robots.common import cables, effector, fixed_by_box, landmark
from pliant.robots.parameters import CableReach, Cables, Damping, Gravity, Meshing, Solid, TotalMass
from pliant.robots.scene import builder
from pliant.solvers.base import number_option

_AZIMUTHS = [math.pi / 2, math.pi, 3 * math.pi / 2, 0.0]  # +y, -x, -y, +x


def reference_cable_paths() -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Cable paths of the SoftRobots Trunk scene (for its reference mesh).

    The cables converge along the taper from radius 10 mm at the base to 2 mm at the tip:
    pairs of points at 21 and 27 mm from every 17.5 mm step along the direction
    (0, 2 - 10, 195) normalised; 20 points for the long cables, 9 for the short ones.
    """
    d = np.array([0.0, -8.0, 195.0]) / np.linalg.norm([0.0, -8.0, 195.0])
    steps = np.repeat(np.arange(10) * 17.5, 2)
    offsets = np.tile([21.0, 27.0], 10)
    radius = d[1] * steps + 10.0
    z = d[2] * steps + offsets
    paths, pulls = [], []
    for n in range(8):
        a = _AZIMUTHS[n % 4]
        radial = np.array([math.cos(a), math.sin(a), 0.0])
        pts = radius[:, None] * radial + z[:, None] * np.array([0.0, 0.0, 1.0])
        paths.append(pts if n < 4 else pts[:9])
        pulls.append(10.0 * radial)
    return paths, pulls


# The SoftRobots/SofaGym Trunk's silicone, mass, gravity (it lies along +z, under -y), damping
# and cables, shared by the scenes built on it (pliant.robots.trunk_cube).
TRUNK = (
    Solid(450.0, 0.45, mass="uniform"),
    TotalMass(0.042),
    Gravity((0.0, -9810.0, 0.0)),
    Damping(0.1, 0.1),
    Cables(max_displacement_change=1.0),
    CableReach(),
)


@builder(Meshing(5.2), *TRUNK)
def trunk(
    p,
    *,
    lag_tolerance: float = 0.005,
) -> Model:
    """The Trunk: a tapered cylinder along +z, base fixed, lying horizontally under gravity -y.

    Defaults are the SoftRobots/SofaGym Trunk (E = 450 kPa, nu = 0.45, 0.042 kg, Rayleigh
    0.1/0.1, long cables at most 70 mm, short ones 40 mm, 1 mm per step at most).

    `lag_tolerance`: the lagged tangent's largest frame change before a refactorisation
    (:mod:`pliant.solvers.system`; the bodies' default is 0.02). The Trunk swings and bends
    through large rotations, and the lag's error grows with them: pulled by two cables (10 and
    5 mm) it departs from the exact step by 1.94 mm after 1 s at 0.02 (4.6 % of its 42 mm of
    motion), 0.91 mm at 0.01, 0.19 mm (0.45 %) at 0.005, for 837, 768 and 676 steps/s on the
    reference mesh (`pliant bench`, default against exact); 0.005 keeps it within 1 %.
    """
    mesh = p.mesh_or(shapes.trunk)
    box = landmark(mesh, "fixed_box", [[-20.0, -20.0, 0.0], [20.0, 20.0, 20.0]])
    body = p.tet_body(mesh, fixed_nodes=fixed_by_box(mesh, box))
    body.lag_tolerance = number_option(lag_tolerance, "lag_tolerance", above=0.0)
    ref_paths, ref_pulls = reference_cable_paths()
    paths = [landmark(mesh, f"cable_points_{i}", ref_paths[i]) for i in range(8)]
    pulls = [landmark(mesh, f"pull_points_{i}", ref_pulls[i])[0] for i in range(8)]
    acts = cables(mesh, body, paths, pulls, p.cables, p.reach.limits())
    eff = effector(mesh, body, landmark(mesh, "effector", [0.0, 0.0, 195.0]))
    return Model(body, actuators=acts, effectors=[eff], name="trunk")


def demo_actuation(t: float) -> np.ndarray:
    """Pull a long cable to 30 mm, then a short one to 20 mm on the opposite side, then release."""
    values = np.zeros(8)
    values[0] = 30.0 * min(t, 1.0)
    values[6] = 20.0 * min(max(t - 1.0, 0.0), 1.0)
    if t > 2.0:
        values *= max(0.0, 3.0 - t)
    return values


def circle(n: int = 30, *, radius: float = 30.0, height: float = 180.0) -> np.ndarray:
    a = np.linspace(0.0, 2.0 * math.pi, n, endpoint=False)
    return np.column_stack([radius * np.cos(a), radius * np.sin(a), np.full(n, height)])
