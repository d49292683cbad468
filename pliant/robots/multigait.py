"""The Multigait pneumatic quadruped on the ground (thesis §3.1.2, §3.4.1).

How the gait moves it (measured on the default mesh, experiments/multigait_gait.py): an
inflated leg curls towards the floor and lifts its hip, so that it stands on the edge of its
tip; the inflated centre arches the body and lifts it onto the legs. The pressure that curls a
leg also stretches its floor (the coarse elements of the strain-limiting layer cannot be both
inextensible and free to bend), so an inflated chamber lengthens the robot between its
contacts (by up to a millimetre) more than the curl shortens it; on each change, the side that
stands on fewer, less loaded contacts slides. Over the hand-defined gait this makes the robot
travel about 0.4 mm per cycle along +x, towards the legs it inflates first. SofaGym's
Multigait, whose paper layer is an inextensible membrane, travels the other way (its test
script inflates the legs at low x first and its reward counts +x progress), by centimetres:
there the curled legs and the arched centre shorten the robot. Finer meshes with a stiffer
layer (mesh_size 3, layer_stiffness 70) do shorten it, but then barely move (0.05 mm/cycle).
"""

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
    mesh_size: float = 6.0,
    young_modulus: float = 70.0,
    poisson_ratio: float = 0.05,
    total_mass: float = 0.035,
    material: MaterialName = "neo-hookean",
    gravity: tuple[float, float, float] = (0.0, 0.0, -9810.0),
    rayleigh_mass: float = 0.1,
    rayleigh_stiffness: float = 0.1,
    friction: float = 0.7,
    collision_points: np.ndarray | None = None,
    collision_spacing: float = 20.0,
    cavity_mode: str = "pressure",
    max_pressure: float = 50.0,
    layer_thickness: float = 1.0,
    layer_stiffness: float = 20.0,
) -> Model:
    """The Multigait body on a floor at z = 0, five chambers (CHAMBERS order).

    Values of the SOFA Multigait scenes by default (E = 70 kPa, nu = 0.05, 35 g, friction
    0.7); the silicone is Neo-Hookean: at the gait's pressure (about half of E) the thin roofs
    over the slots strain by tens of percent, and the corotational law lets them collapse
    (elements invert from about 35 kPa on the default mesh). A Neo-Hookean chamber has a
    balloon's pressure limit: above about 33 kPa the centre chamber of the default mesh
    inflates without bound (65 times its volume at 35 kPa). `mesh`: a mesh whose surfaces hold
    'cavity_<chamber>' walls (Pliant's parametric mesh by default, or the SOFA reference mesh
    with walls from :func:`pliant.mesh.multigait.reference_cavity_surfaces`).
    `collision_points` (k, 3): the points that touch the floor (the SOFA scene's collision
    surface vertices); default: underside nodes, one per `collision_spacing` mm cell, and
    the corners of the underside's outline with a node every `collision_spacing` mm along it.
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
    """Nodes of the underside, one per `spacing` x `spacing` cell (the closest to its centre),
    and along its outline the corners and a node every `spacing` mm: a curled leg rests on
    the edge of its tip."""
    z = mesh.points[:, 2]
    bottom = z <= z.min() + 1e-6 * np.ptp(mesh.points)
    triangles = mesh.boundary_triangles()
    underside = triangles[np.all(bottom[triangles], axis=1)]
    edges = np.sort(underside[:, [[0, 1], [1, 2], [2, 0]]].reshape(-1, 2), axis=1)
    edges, count = np.unique(edges, axis=0, return_counts=True)
    return np.union1d(
        _thinned(mesh, np.flatnonzero(bottom), spacing),
        _along_outline(mesh.points[:, :2], edges[count == 1], spacing),
    )


def _along_outline(xy: np.ndarray, edges: np.ndarray, spacing: float) -> np.ndarray:
    """Corners of the closed polygons made of `edges`, and a node every `spacing` between."""
    neighbours: dict[int, list[int]] = {}
    for a, b in edges:
        neighbours.setdefault(int(a), []).append(int(b))
        neighbours.setdefault(int(b), []).append(int(a))
    kept, seen = [], set()
    for start in neighbours:
        if start in seen:
            continue
        loop, previous, node = [start], None, start
        for _ in range(len(edges)):
            seen.add(node)
            nxt = next(n for n in neighbours[node] if n != previous)
            if nxt == start:
                break
            loop.append(nxt)
            previous, node = node, nxt
        else:
            raise ModelError("the outline of the Multigait's underside is not a set of loops")
        points = xy[loop]
        incoming = points - np.roll(points, 1, axis=0)
        outgoing = np.roll(points, -1, axis=0) - points
        cross = incoming[:, 0] * outgoing[:, 1] - incoming[:, 1] * outgoing[:, 0]
        corner = np.abs(cross) > 1e-3 * np.linalg.norm(incoming, axis=1) * np.linalg.norm(
            outgoing, axis=1
        )
        travelled = 0.0
        for k in range(len(loop)):
            travelled += float(np.linalg.norm(incoming[k]))
            if corner[k] or travelled >= spacing:
                kept.append(loop[k])
                travelled = 0.0
    return np.array(sorted(kept), dtype=np.int64)


def _thinned(mesh: TetMesh, nodes: np.ndarray, spacing: float) -> np.ndarray:
    """Of `nodes`, the closest to the centre of each `spacing` x `spacing` cell in x, y."""
    xy = mesh.points[nodes, :2]
    cell = np.floor((xy - xy.min(axis=0)) / spacing).astype(np.int64)
    centre = (cell + 0.5) * spacing + xy.min(axis=0)
    order = np.lexsort((np.linalg.norm(xy - centre, axis=1), cell[:, 1], cell[:, 0]))
    keys = cell[order]
    first = np.ones(len(order), dtype=bool)
    first[1:] = np.any(keys[1:] != keys[:-1], axis=1)
    return np.sort(nodes[order[first]])


def demo_actuation(t: float, *, pressure: float = 30.0, phase: float = 0.6) -> np.ndarray:
    """The hand-defined gait: each group inflated in turn (rear legs, centre, front legs),
    then deflated in the same order; one phase every `phase` seconds (SofaGym's Multigait
    action lasts 0.6 s), ramped over a phase."""
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


def centre_of_mass(model: Model, positions: np.ndarray) -> np.ndarray:
    """(3,) the body's centre of mass at `positions` (n, 3): how far the robot has walked."""
    return model.body.node_masses @ positions / model.body.node_masses.sum()
