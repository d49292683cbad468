"""The Multigait pneumatic quadruped on the ground (thesis §3.1.2, §3.4.1)."""

from __future__ import annotations

import numpy as np

from pliant.constraints.base import EmbeddedPoints
from pliant.constraints.cavity import CavityActuator
from pliant.constraints.collision import Plane
from pliant.constraints.contact import Contacts
from pliant.errors import ModelError
from pliant.fem.body import TetBody
from pliant.mesh import multigait as geometry
from pliant.mesh.tetmesh import TetMesh
from pliant.model import Model
from pliant.robots.common import MaterialName, make_material

# Thesis §3.4.1: inflate the rear legs, the centre, the front legs, then deflate in that order.
GAIT = (
    ("rear_left", "rear_right"),
    ("centre",),
    ("front_left", "front_right"),
)


def multigait(
    *,
    mesh: TetMesh | None = None,
    mesh_size: float = 4.0,
    young_modulus: float = 70.0,
    poisson_ratio: float = 0.45,
    total_mass: float = 0.035,
    material: MaterialName = "corotational",
    gravity: tuple[float, float, float] = (0.0, 0.0, -9810.0),
    rayleigh_mass: float = 0.1,
    rayleigh_stiffness: float = 0.1,
    friction: float = 0.7,
    collision_points: np.ndarray | None = None,
    collision_spacing: float = 8.0,
    cavity_mode: str = "pressure",
    max_pressure: float = 50.0,
    layer_thickness: float = 1.0,
    layer_stiffness: float = 20.0,
) -> Model:
    """The Multigait body on a floor at z = 0, five chambers (CHAMBERS order).

    SOFA scene values by default (E = 70 kPa, nu = 0.45, 35 g). `mesh`: a mesh whose surfaces
    hold 'cavity_<chamber>' walls (Pliant's parametric mesh by default, or the SOFA reference
    mesh with walls from :func:`pliant.mesh.multigait.reference_cavity_surfaces`).
    `collision_points` (k, 3): the points that touch the floor (the SOFA scene's collision
    surface vertices); default: the underside nodes thinned to one per `collision_spacing` mm.
    `cavity_mode`: "pressure" (kPa) or "volume" (mm^3 of growth), up to `max_pressure` kPa.
    The elements of the underside's `layer_thickness` mm are `layer_stiffness` times stiffer:
    the strain-limiting layer (paper in the real robot) that makes an inflated leg bend down
    instead of ballooning.
    """
    mesh = mesh if mesh is not None else geometry.multigait(mesh_size=mesh_size)
    missing = [c for c in geometry.CHAMBERS if f"cavity_{c}" not in mesh.surfaces]
    if missing:
        raise ModelError(f"the Multigait mesh has no walls for the chambers {missing}")
    modes = {"pressure": "force", "volume": "displacement"}
    if cavity_mode not in modes:
        raise ModelError(f"cavity_mode must be 'pressure' or 'volume', got {cavity_mode!r}")
    body = TetBody(
        mesh,
        make_material(material, young_modulus, poisson_ratio),
        total_mass=total_mass,
        gravity=gravity,
        rayleigh_mass=rayleigh_mass,
        rayleigh_stiffness=rayleigh_stiffness,
    )
    z = mesh.points[:, 2]
    layer = np.all(z[mesh.tets] <= z.min() + layer_thickness + 1e-9, axis=1)
    body.mu[layer] *= layer_stiffness
    body.lam[layer] *= layer_stiffness
    chambers = [
        CavityActuator(
            mesh.surfaces[f"cavity_{c}"],
            body.rest_positions,
            name=c,
            mode=modes[cavity_mode],
            max_force=max_pressure,
        )
        for c in geometry.CHAMBERS
    ]
    points = (
        EmbeddedPoints(mesh, collision_points)
        if collision_points is not None
        else EmbeddedPoints.at_nodes(_underside_nodes(mesh, collision_spacing))
    )
    floor = Plane(point=(0.0, 0.0, float(mesh.points[:, 2].min())))
    contacts = Contacts([floor], friction=friction, margin=1.0, points=points)
    return Model(body, actuators=chambers, contacts=contacts, name="multigait")


def _underside_nodes(mesh: TetMesh, spacing: float) -> np.ndarray:
    """Nodes of the underside, one per `spacing` x `spacing` cell (the closest to its centre)."""
    z = mesh.points[:, 2]
    under = np.flatnonzero(z <= z.min() + 1e-6 * np.ptp(mesh.points))
    xy = mesh.points[under, :2]
    cell = np.floor((xy - xy.min(axis=0)) / spacing).astype(np.int64)
    centre = (cell + 0.5) * spacing + xy.min(axis=0)
    order = np.lexsort((np.linalg.norm(xy - centre, axis=1), cell[:, 1], cell[:, 0]))
    keys = cell[order]
    first = np.ones(len(order), dtype=bool)
    first[1:] = np.any(keys[1:] != keys[:-1], axis=1)
    return np.sort(under[order[first]])


def demo_actuation(t: float, *, pressure: float = 12.0, phase: float = 0.4) -> np.ndarray:
    """The hand-defined gait: each group inflated in turn (rear legs, centre, front legs),
    then deflated in the same order; one phase every `phase` seconds, ramped over a phase."""
    groups = len(GAIT)
    k, frac = divmod(t / phase, 1.0)
    k = int(k) % (2 * groups)
    level = np.zeros(len(geometry.CHAMBERS))
    for g, names in enumerate(GAIT):
        if g < k < groups + g:
            on = 1.0
        elif k == g:
            on = frac
        elif k == groups + g:
            on = 1.0 - frac
        else:
            on = 0.0
        for name in names:
            level[geometry.CHAMBERS.index(name)] = on
    return pressure * level
