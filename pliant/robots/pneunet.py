"""A PneuNet pneumatic finger: sealed chambers inflated together."""

from __future__ import annotations

import math

import numpy as np

from pliant.constraints.cavity import CavityActuator
from pliant.errors import ModelError
from pliant.fem.body import TetBody
from pliant.mesh import shapes
from pliant.mesh.tetmesh import TetMesh
from pliant.model import Model
from pliant.robots.common import MaterialName, effector, fixed_by_box, make_material
from pliant.robots.finger import SILICONE_DENSITY


def pneunet(
    *,
    mesh: TetMesh | None = None,
    mesh_size: float = 6.0,
    n_chambers: int = 6,
    young_modulus: float = 500.0,
    poisson_ratio: float = 0.3,
    density: float = SILICONE_DENSITY,
    material: MaterialName = "corotational",
    mass: str = "lumped",
    gravity: tuple[float, float, float] = (0.0, 0.0, -9810.0),
    rayleigh_mass: float = 0.0,
    rayleigh_stiffness: float = 0.1,
    cavity_mode: str = "pressure",
    max_pressure: float = 100.0,
    max_volume_growth: float = math.inf,
    max_volume_change: float | None = None,
) -> Model:
    """PneuNet finger along +x, fixed at x = 0; one actuator inflates all chambers together.

    cavity_mode: "pressure" (lambda = pressure, kPa with mm units) or "volume" (imposed volume
    growth, mm^3). Defaults follow the SoftRobots PneuNet (E = 500 kPa, nu = 0.3).
    """
    mesh = mesh if mesh is not None else shapes.pneunet(mesh_size=mesh_size, n_chambers=n_chambers)
    body = TetBody(
        mesh,
        make_material(material, young_modulus, poisson_ratio),
        density=density,
        mass=mass,
        fixed_nodes=fixed_by_box(mesh, mesh.landmarks["fixed_box"]),
        gravity=gravity,
        rayleigh_mass=rayleigh_mass,
        rayleigh_stiffness=rayleigh_stiffness,
    )
    modes = {"pressure": "force", "volume": "displacement"}
    if cavity_mode not in modes:
        raise ModelError(f"cavity_mode must be 'pressure' or 'volume', got {cavity_mode!r}")
    mode = modes[cavity_mode]
    cavity = CavityActuator(
        mesh.surfaces["cavity"],
        body.rest_positions,
        name="cavity",
        mode=mode,
        min_force=0.0,
        max_force=max_pressure,
        max_displacement=max_volume_growth,
        max_displacement_change=max_volume_change,
    )
    eff = effector(mesh, body, mesh.landmarks["effector"])
    return Model(body, actuators=[cavity], effectors=[eff], name="pneunet")


def demo_actuation(t: float) -> np.ndarray:
    """Inflate to 30 kPa over a second, hold, deflate."""
    return np.array([30.0 * min(t, 1.0) * (1.0 if t < 2.0 else max(0.0, 3.0 - t))])


def bending(
    n: int = 20, *, tip: tuple[float, float, float] = (114.0, 0.0, 4.0), drop: float = 25.0
) -> np.ndarray:
    a = np.linspace(0.0, 1.0, n)
    x0, y0, z0 = tip
    return np.column_stack([x0 - 0.2 * drop * a**2, np.full(n, y0), z0 - drop * a])
