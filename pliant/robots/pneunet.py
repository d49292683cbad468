"""A PneuNet pneumatic finger: sealed chambers inflated together."""

from __future__ import annotations

import math

import numpy as np

from pliant.mesh import shapes
from pliant.model import Model
from pliant.robots import common
from pliant.robots.common import cavity, curling, effector, fixed_by_box
from pliant.robots.parameters import Damping, Density, Gravity, Meshing, Solid
from pliant.robots.scene import builder


@builder(Meshing(6.0), Solid(500.0, 0.3), Density(), Gravity.Z, Damping(0.0, 0.1))
def pneunet(
    p,
    *,
    n_chambers: int = 6,
    cavity_mode: str = "pressure",
    max_pressure: float = 100.0,
    max_volume_growth: float = math.inf,
    max_volume_change: float | None = None,
) -> Model:
    """PneuNet finger along +x, fixed at x = 0; one actuator inflates all chambers together.

    cavity_mode: "pressure" (lambda = pressure, kPa with mm units) or "volume" (imposed volume
    growth, mm^3). Defaults follow the SoftRobots PneuNet (E = 500 kPa, nu = 0.3).
    """
    mesh = p.mesh_or(shapes.pneunet, n_chambers=n_chambers)
    body = p.tet_body(mesh, fixed_nodes=fixed_by_box(mesh, mesh.landmarks["fixed_box"]))
    chambers = cavity(
        mesh,
        body,
        "cavity",
        mode=common.cavity_mode(cavity_mode),
        max_pressure=max_pressure,
        max_displacement=max_volume_growth,
        max_displacement_change=max_volume_change,
    )
    eff = effector(mesh, body, mesh.landmarks["effector"])
    return Model(body, actuators=[chambers], effectors=[eff], name="pneunet")


def demo_actuation(t: float) -> np.ndarray:
    """Inflate to 30 kPa over a second, hold, deflate."""
    return np.array([30.0 * min(t, 1.0) * (1.0 if t < 2.0 else max(0.0, 3.0 - t))])


def bending(
    n: int = 20, *, tip: tuple[float, float, float] = (114.0, 0.0, 4.0), drop: float = 25.0
) -> np.ndarray:
    return curling(n, tip, drop, 0.2)
