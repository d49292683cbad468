"""The Multigait pneumatic quadruped on the ground (thesis §3.1.2, §3.4.1).

How the hand-defined gait walks it (measured on the default mesh, dt = 0.01 s, 0.6 s phases,
experiments/reduction/multigait_gait.py): the paper under the real robot, a membrane here as in
SofaGym (a triangle layer of E = 5000 kPa, 1 mm, on the underside), keeps the underside's length, so
an inflated leg curls and draws its tip in towards the body. Which end slides is the one that
carries less of the weight. While the rear legs curl, the robot rests on its flat front half
(all of its weight), so the rear tips draw in, by 8 mm, and the front stays. Once the rear legs
are deflated and flat again they carry the robot, and the curled front legs, deflated last,
unroll forward. Each cycle moves both ends of the underside and the centre of mass 6.2 mm
towards the front legs, -x, away from the legs inflated first (6.4 mm on the first cycle,
from rest), about 4.5 % of the body length; with friction 0.4 or 1.0 instead of 0.7: 6.5 and
6.3 mm on the first cycle, with dt = 0.005 s: 6.4 mm, on a finer mesh (mesh_size 4): 6.3 mm;
coarser meshes resolve the curl less (mesh_size 9: 3.8 mm, 12: 0.9 mm).
SofaGym's complete model goes 36 mm in its six-action episode (thesis Table 3.2).

The chambers are volume-controlled, as SofaGym's (volume growth of 1500 mm^3 per leg and
2000 mm^3 in the centre, about 4.8 and 3.9 times its chambers' volumes): a Neo-Hookean chamber
is a balloon whose pressure peaks (about 33 kPa for the default mesh's centre), so that a
pressure command above the peak inflates it without bound, while the volume command passes
the peak at a bounded pressure (42 kPa at most over the gait). At a pressure of 30 kPa the
gait moves the robot 1.5 mm on its first cycle. Without the membrane (stiffening the floor's
tetrahedra cannot do its work: one linear element through a layer locks in bending), the
pressure stretches the floor, an inflated leg lengthens by up to 19 mm instead of drawing in,
and the gait moves the robot 1.2 mm per cycle the wrong way, towards the legs inflated first.
"""

from __future__ import annotations

import functools

import numpy as np

from pliant.constraints.base import EmbeddedPoints
from pliant.errors import ModelError
from pliant.fem.membrane import Membrane
from pliant.geometry.collision import Plane
from pliant.mesh import multigait as geometry
from pliant.mesh.tetmesh import TetMesh
from pliant.model import Model
from pliant.robots import common
from pliant.robots.common import cavity
from pliant.robots.parameters import Contact, Damping, Gravity, Meshing, Solid, TotalMass
from pliant.robots.scene import builder

# Thesis §3.4.1: inflate the rear legs, the centre, the front legs, then deflate in that order.
GAIT = (
    ("rear_left", "rear_right"),
    ("centre",),
    ("front_left", "front_right"),
)


@builder(
    Meshing(6.0),
    Solid(70.0, 0.05, material="neo-hookean"),
    TotalMass(0.035),
    Gravity.Z,
    Damping(0.1, 0.1),
    Contact(0.7, contact_margin=1.0),
)
def multigait(
    p,
    *,
    collision_points: np.ndarray | None = None,
    collision_spacing: float = 20.0,
    cavity_mode: str = "volume",
    max_pressure: float = 50.0,
    membrane_stiffness: float = 5000.0,
    membrane_poisson_ratio: float = 0.49,
) -> Model:
    """The Multigait body on a floor at z = 0, five chambers (CHAMBERS order).

    Values of the SOFA Multigait scenes by default (E = 70 kPa, nu = 0.05, 35 g, friction
    0.7); the silicone is Neo-Hookean: at the gait's pressure (about half of E) the thin roofs
    over the slots strain by tens of percent, and the corotational law lets them collapse
    (elements invert within the first gait phase on the default mesh). `mesh`: a mesh whose
    surfaces hold 'cavity_<chamber>' walls (Pliant's parametric mesh by default, or the SOFA
    reference mesh with walls from :func:`pliant.mesh.multigait.reference_cavity_surfaces`).
    `collision_points` (k, 3): the points that touch the floor (the SOFA scene's collision
    surface vertices); default: underside nodes, one per `collision_spacing` mm cell, and
    the corners of the underside's outline with a node every `collision_spacing` mm along it.
    `cavity_mode`: "volume" (mm^3 of growth, SofaGym's command) or "pressure" (kPa), at most
    `max_pressure` kPa either way. The strain-limiting layer (paper in the real robot) is a
    membrane on the underside's triangles, of stretch stiffness `membrane_stiffness` (E t,
    kPa mm; SofaGym's 5000 kPa, 1 mm) and Poisson ratio `membrane_poisson_ratio`; 0 leaves it
    out. It keeps the underside's length and lets it bend, so that an inflated leg curls.
    """
    mesh = p.mesh_or(geometry.multigait)
    missing = [c for c in geometry.CHAMBERS if f"cavity_{c}" not in mesh.surfaces]
    if missing:
        raise ModelError(f"the Multigait mesh has no walls for the chambers {missing}")
    mode = common.cavity_mode(cavity_mode)
    paper = (
        [
            Membrane(
                mesh.points,
                _face_triangles(mesh),
                stretch_stiffness=membrane_stiffness,
                poisson_ratio=membrane_poisson_ratio,
            )
        ]
        if membrane_stiffness != 0
        else []
    )
    body = p.tet_body(mesh, membranes=paper)
    chambers = [
        cavity(mesh, body, f"cavity_{c}", name=c, mode=mode, max_pressure=max_pressure)
        for c in geometry.CHAMBERS
    ]
    points = (
        EmbeddedPoints(mesh, collision_points)
        if collision_points is not None
        else EmbeddedPoints.at_nodes(_face_nodes(mesh, collision_spacing))
    )
    floor = Plane(point=(0.0, 0.0, float(mesh.points[:, 2].min())))
    contacts = p.contacts([floor], points=points)
    return Model(body, actuators=chambers, contacts=contacts, name="multigait")


@functools.cache
def face_points(
    mesh_size: float = 6.0, collision_spacing: float = 20.0, *, top: bool = False
) -> np.ndarray:
    """(k, 3) the default model's colliding points at rest (its underside nodes, one per
    `collision_spacing` cell, and its outline's); with `top`, the same of the top face after
    them: what a proxy skins to touch the floor through the FEM's surface, on either face of
    the slab a curled leg may roll onto (:func:`pliant.proxy.multigait_proxy`). Read-only."""
    mesh = geometry.multigait(mesh_size=mesh_size)
    faces = (False, True) if top else (False,)
    nodes = np.concatenate([_face_nodes(mesh, collision_spacing, top=t) for t in faces])
    points = mesh.points[nodes].copy()
    points.flags.writeable = False
    return points


def _face(mesh: TetMesh, *, top: bool = False) -> np.ndarray:
    """(n,) bool: the nodes on the flat underside (or the flat top)."""
    z = mesh.points[:, 2]
    tolerance = 1e-6 * np.ptp(mesh.points)
    return z >= z.max() - tolerance if top else z <= z.min() + tolerance


def _face_triangles(mesh: TetMesh, *, top: bool = False) -> np.ndarray:
    """(t, 3) the boundary triangles of the flat underside (or top)."""
    triangles = mesh.boundary_triangles()
    return triangles[np.all(_face(mesh, top=top)[triangles], axis=1)]


def _face_nodes(mesh: TetMesh, spacing: float, *, top: bool = False) -> np.ndarray:
    """Nodes of the underside (or top), one per `spacing` x `spacing` cell (the closest to
    its centre), and along its outline the corners and a node every `spacing` mm: a curled
    leg rests on the edge of its tip."""
    face = _face_triangles(mesh, top=top)
    edges = np.sort(face[:, [[0, 1], [1, 2], [2, 0]]].reshape(-1, 2), axis=1)
    edges, count = np.unique(edges, axis=0, return_counts=True)
    return np.union1d(
        _thinned(mesh, np.flatnonzero(_face(mesh, top=top)), spacing),
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


#: The hand gait's volume growths (mm^3) of the inflated centre and of each inflated leg.
GAIT_AMPLITUDE = (4900.0, 3300.0)


def chamber_amplitudes(amplitude: tuple[float, float] = GAIT_AMPLITUDE) -> np.ndarray:
    """(5,) each chamber's command when inflated, in CHAMBERS order: the centre's, then a
    leg's for each leg."""
    centre, leg = amplitude
    return np.where(np.array(geometry.CHAMBERS) == "centre", centre, leg)


def demo_actuation(
    t: float, *, amplitude: tuple[float, float] = GAIT_AMPLITUDE, phase: float = 0.6
) -> np.ndarray:
    """The hand-defined gait: each group inflated in turn (rear legs, centre, front legs),
    then deflated in the same order; one phase every `phase` seconds (SofaGym's Multigait
    action lasts 0.6 s), ramped over a phase. `amplitude`: the command of the inflated centre
    and of each inflated leg, in the chambers' unit: mm^3 of volume growth for the default
    volume-controlled model (3.9 and 4.8 times the rest volumes of the default mesh's chambers,
    as SofaGym's 2000 and 1500 mm^3 are of the reference mesh's), kPa for a
    pressure-controlled one."""
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
    return level * chamber_amplitudes(amplitude)


def centre_of_mass(model: Model, positions: np.ndarray) -> np.ndarray:
    """(3,) the body's centre of mass at `positions` (n, 3): how far the robot has walked."""
    return model.body.node_masses @ positions / model.body.node_masses.sum()
