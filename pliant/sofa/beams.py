"""Beams of SOFA's BeamAdapter plugin, read into a Pliant :class:`~pliant.fem.rod.RodBody`.

BeamAdapter's beam (SofaGym's StemPendulum builds one) is a Rigid3 ``MechanicalObject`` on an
edge topology (``EdgeSetTopologyContainer``, ``MeshTopology`` or ``RegularGridTopology`` edges),
with a ``BeamInterpolation`` that gives each edge its section and material and an
``AdaptiveBeamForceFieldAndMass`` that makes it a beam element with mass. What BeamAdapter's
source computes, and how Pliant reads it:

* the section: circular (``radius``, ``innerRadius``; I = pi (r^4 - r_i^4) / 4 about both
  axes, J = 2 I) or rectangular (``lengthY``, ``lengthZ``; J = Iy + Iz), SOFA's defaults
  radius 1, E 1e5 (``defaultYoungModulus``), nu 0.4 (``defaultPoissonRatio``); one value, or
  one per edge when they agree (Pliant's rod has one section; Young's moduli may differ per
  edge);
* the element: axial E A / L, torsion G J / L, bending E I, **no shear deformation**
  (BeamAdapter's shear areas are zero: its element is Euler-Bernoulli's, corotational). Pliant's
  element is a geometrically exact Cosserat rod's; its shear stiffness is raised here so that
  shear adds at most 1e-4 of the bending compliance of the shortest element (the
  Euler-Bernoulli limit; one-point quadrature keeps it free of locking). Departure: Pliant's
  element is the rod's, not BeamAdapter's cubic Hermite beam: the same energy, discretised
  otherwise (a cantilever under a tip load converges to F L^3 / (3 E I) as 1 / N^2: 0.2 %
  at 10 elements);
* the rest shape: ``straight`` (BeamAdapter's default) rests each element straight along its
  first frame's x axis, so the rest curvature is zero; ``straight=False`` rests at the
  initial frames (SofaGym's stems);
* the mass: ``massDensity`` times the section's area per length (one value or one per
  edge; ``computeMass=False``: none), lumped at the nodes with the rotary inertia rho I per
  length (BeamAdapter's mass matrix is the consistent one: the same total mass and first
  moment; departure in the distribution only); ``UniformMass`` on the frames adds point
  masses (``totalMass`` shared by its ``indices``, or ``vertexMass`` each, with their
  isotropic inertia);
* the frames' axes: SOFA's x along the beam, y and z across: Pliant's d3, d1, d2 (as the
  Cosserat rods of :mod:`pliant.sofa.rods`).

Held and loaded frames (any frame, by its index): ``FixedConstraint`` (a clamp),
``PartialFixedConstraint``'s six directions (world axes, the three last the rotation's),
``RestShapeSpringsForceField`` springs to the rest pose (``stiffness`` on positions,
``angularStiffness`` on the turn from rest; their ``points``, or every frame),
``ConstantForceField`` forces and moments (read again before each step: a controller sets them),
the root's gravity, the ODE solver's Rayleigh damping. Collision models carried by the frames
(``RigidMapping`` children) collide with the scene's static obstacles as a Cosserat rod's
do. A ``UniformMass`` index beyond the frames is outside SOFA's state too (SOFA does not check
it: its memory past the state's end); Pliant leaves such indices out with a
:class:`BeamIndexWarning`.

Written back after each step: the frames' poses and velocities, and the points the frames
carry (RigidMapping, IdentityMapping).
"""

from __future__ import annotations

import dataclasses
import warnings
from typing import TYPE_CHECKING

import numpy as np
from scipy.spatial.transform import Rotation

from pliant.errors import ModelError
from pliant.fem.loads import NodalForces, RestShapeSprings, RotationSprings
from pliant.fem.material import Material
from pliant.fem.rod import RodBody, RodSection
from pliant.model import Model, State
from pliant.sofa import rods
from pliant.sofa.rigids import _rigid_mass_values
from pliant.sofa.servos import rigid_pose
from pliant.sofa.tree import SceneError, SceneNode, SceneObject, data_value

if TYPE_CHECKING:
    from pliant.sofa.loader import _Builder

INTERPOLATION = "BeamInterpolation"
FORCEFIELD = "AdaptiveBeamForceFieldAndMass"
COMPONENTS = frozenset({INTERPOLATION, FORCEFIELD})
# BeamInterpolation's defaults (BeamAdapter's source).
DEFAULT_YOUNG, DEFAULT_POISSON = 1.0e5, 0.4
# Shear compliance left to Pliant's rod, as a share of the shortest element's bending one.
SHEAR_SHARE = 1e-4
EDGE_TOPOLOGIES = ("EdgeSetTopologyContainer", "MeshTopology", "RegularGridTopology")
FIXED = ("FixedConstraint", "FixedProjectiveConstraint")
PARTIAL = ("PartialFixedConstraint", "PartialFixedProjectiveConstraint")


def _flag_on(obj: SceneObject, key: str, default: bool = False) -> bool:
    value = obj.attrs.get(key, default)
    if isinstance(value, str):
        return value.strip().lower() in ("1", "true", "yes")
    return bool(np.asarray(data_value(value)).reshape(-1)[0])


class BeamIndexWarning(UserWarning):
    """A component on a beam names frames the beam does not have (left out)."""


def has_beams(root: SceneNode) -> bool:
    """Whether the scene holds a BeamAdapter beam (a BeamInterpolation)."""
    return any(o.type == INTERPOLATION for n in root.walk() for o in n.objects)


def _numbers(obj: SceneObject, key: str, default) -> np.ndarray:
    return np.asarray(data_value(obj.attrs.get(key, default)), dtype=float).reshape(-1)


def _one_value(obj: SceneObject, key: str, default: float, edges: int) -> float:
    values = _numbers(obj, key, [default])
    if values.size not in (1, edges) or not np.all(values == values[0]):
        raise SceneError(
            f"{obj.path}.{key}: one value for every edge (Pliant's beam has one section),"
            f" got {values.tolist()}"
        )
    return float(values[0])


def _per_edge(obj: SceneObject, key: str, default: float, edges: int) -> np.ndarray:
    values = _numbers(obj, key, [default])
    if values.size not in (1, edges) or not np.all(np.isfinite(values)) or np.any(values < 0):
        raise SceneError(
            f"{obj.path}.{key}: one value, or one per edge ({edges}), finite and >= 0 expected"
        )
    return np.broadcast_to(values, (edges,)).copy()


def _section(interpolation: SceneObject, edges: int) -> RodSection:
    """The section, one for every edge (:func:`pliant.sofa.rods.sofa_section`)."""
    return rods.sofa_section(
        interpolation, lambda key, default: _one_value(interpolation, key, default, edges)
    )


def _edges(builder: _Builder, node: SceneNode, count: int) -> np.ndarray:
    """The beam's edges: its topology's, or the frames in order."""
    topology = next((o for o in node.objects if o.type in EDGE_TOPOLOGIES), None)
    if topology is None or topology.type == "RegularGridTopology":
        return np.column_stack([np.arange(count - 1), np.arange(1, count)])
    raw = topology.attrs.get("edges")
    if isinstance(raw, str) and raw.startswith("@"):
        source = builder.link(node, raw.split(".")[0])
        raw = None if source is None else source.attrs.get("edges")
    edges = np.asarray(data_value(raw if raw is not None else []), dtype=float).reshape(-1)
    if edges.size == 0:
        return np.column_stack([np.arange(count - 1), np.arange(1, count)])
    edges = edges.astype(np.int64)
    if edges.size % 2 or edges.min() < 0 or edges.max() >= count:
        raise SceneError(f"{topology.path}.edges: pairs of frame indices in [0, {count}) expected")
    return edges.reshape(-1, 2)


def _indices(obj: SceneObject, key: str, count: int, default: np.ndarray | None) -> np.ndarray:
    if key not in obj.attrs or not np.asarray(data_value(obj.attrs[key])).size:
        return np.arange(count) if default is None else default
    idx = _numbers(obj, key, []).astype(np.int64)
    if idx.min() < 0 or idx.max() >= count:
        raise SceneError(f"{obj.path}.{key}: indices in [0, {count}) expected, got {idx.tolist()}")
    return idx


@dataclasses.dataclass
class _Beam:
    """One beam of the scene: its components and its frames at rest."""

    dofs: SceneObject  # the Rigid3 MechanicalObject of the frames
    interpolation: SceneObject
    forcefield: SceneObject
    points: np.ndarray  # (N, 3)
    frames: np.ndarray  # (N, 3, 3) SOFA frames (columns x, y, z)
    edges: np.ndarray  # (E, 2)


def _read_beam(builder: _Builder, interpolation: SceneObject) -> _Beam:
    node = interpolation.node
    forcefields = [
        o
        for o in node.objects
        if o.type == FORCEFIELD
        and builder.link(node, str(o.attrs.get("interpolation", "@" + interpolation.name)))
        is interpolation
    ]
    if len(forcefields) != 1:
        raise SceneError(
            f"{interpolation.path}: one AdaptiveBeamForceFieldAndMass must use it, got"
            f" {len(forcefields)}"
        )
    dofs = builder._one(node, {"MechanicalObject"}, "MechanicalObjects")
    if dofs is None or not str(dofs.attrs.get("template", "")).startswith("Rigid3"):
        raise SceneError(f"{node.path}: a beam's frames are a Rigid3 MechanicalObject")
    count = np.asarray(data_value(dofs.attrs.get("position", [])), float).size // 7
    if count < 2:
        raise SceneError(f"{dofs.path}.position: a beam needs two frames or more")
    poses = [rigid_pose(dofs, k) for k in range(count)]
    points = np.array([p for p, _ in poses])
    frames = np.array([r for _, r in poses])
    if str(interpolation.attrs.get("dofsAndBeamsAligned", "1")).strip().lower() in ("0", "false"):
        raise SceneError(
            f"{interpolation.path}.dofsAndBeamsAligned: beams offset from their frames"
            " (not supported)"
        )
    return _Beam(dofs, interpolation, forcefields[0], points, frames, _edges(builder, node, count))


class BeamData(rods.RodData):
    """The beam's inputs and outputs in the scene's data, around each step (the rod's forces
    re-read before; the frames and the points they carry written after)."""

    def __init__(self, beam: _Beam, body: RodBody, forces: list) -> None:
        self.beam, self.body, self.forces = beam, body, forces
        self.carried: dict = {}

    def read(self, state: State) -> State:
        self.apply_forces()
        return state

    def write(self, state: State) -> None:
        n = self.body.n_centreline
        x, v = state.positions, state.velocities
        sofa = self.body.frames(x) @ rods.AXES.T
        quats = Rotation.from_matrix(sofa).as_quat()
        quats[quats[:, 3] < 0] *= -1.0
        self.beam.dofs.attrs["position"] = rods._frozen(np.hstack([x[:n], quats]))
        self.beam.dofs.attrs["velocity"] = rods._frozen(np.hstack([v[:n], v[n:]]))
        rods.write_carried(self.beam.dofs.node, x[:n], sofa, np.arange(n), self.carried)


def _point_masses(obj: SceneObject, builder: _Builder, count: int) -> list:
    values = _rigid_mass_values(builder, obj)
    idx = _numbers(obj, "indices", []).astype(np.int64)
    idx = np.arange(count) if idx.size == 0 else idx
    outside = idx[(idx < 0) | (idx >= count)]
    if outside.size:
        warnings.warn(
            f"{obj.path}.indices: {outside.tolist()} name no frame of the beam's {count}"
            " (SOFA does not check them); left out",
            BeamIndexWarning,
            stacklevel=2,
        )
    kept = idx[(idx >= 0) & (idx < count)]
    shared = "vertexMass" not in obj.attrs  # totalMass: shared by the indices, as SOFA does
    each = values[0] / len(idx) if shared else values[0]
    inertia = each * float(np.trace(values[2:].reshape(3, 3))) / 3.0
    return [(int(k), float(each), inertia) for k in kept]


def beam_model(builder: _Builder) -> tuple[Model, float, str, BeamData]:
    """The scene's model, its one BeamAdapter beam as the body (see the module text): the
    root's time step, the solver kind and the beam's data to read and write around a step."""
    root, path = builder.root, builder.path
    found = [o for n in root.walk() for o in n.objects if o.type == INTERPOLATION]
    if len(found) != 1:
        names = ", ".join(o.path for o in found)
        raise SceneError(f"{path.name}: Pliant simulates one BeamAdapter beam, got {names}")
    dt, gravity = rods.alone(builder, "a beam")
    beam = _read_beam(builder, found[0])
    node, n, edges = beam.dofs.node, len(beam.points), beam.edges
    m = len(edges)
    polyline = np.array_equal(edges, np.column_stack([np.arange(n - 1), np.arange(1, n)]))
    section = _section(beam.interpolation, m)
    young = _per_edge(beam.interpolation, "defaultYoungModulus", DEFAULT_YOUNG, m)
    poisson = _one_value(beam.interpolation, "defaultPoissonRatio", DEFAULT_POISSON, m)
    try:
        material = Material(float(young.max()), poisson)
    except ModelError as exc:
        raise SceneError(f"{beam.interpolation.path}: {exc}") from exc
    lengths = np.linalg.norm(beam.points[edges[:, 1]] - beam.points[edges[:, 0]], axis=1)
    if lengths.min() <= 0.0:
        raise SceneError(f"{beam.dofs.path}: two frames of an edge at the same place")
    # Euler-Bernoulli: shear stiffness kappa G A with 12 E I / (kappa G A L^2) <= SHEAR_SHARE.
    g = material.mu
    stiff = 12.0 * float(young.max()) * max(section.inertia) / (g * section.area)
    kappa = max(section.shear_coefficient, stiff / (SHEAR_SHARE * float(lengths.min()) ** 2))
    section = dataclasses.replace(section, shear_coefficient=kappa)
    straight = str(beam.interpolation.attrs.get("straight", "1")).strip().lower()
    straight = straight not in ("0", "false")
    if straight:
        axis = beam.frames[edges[:, 0]][:, :, 0]
        chord = (beam.points[edges[:, 1]] - beam.points[edges[:, 0]]) / lengths[:, None]
        if np.abs(np.einsum("ij,ij->i", axis, chord) - 1.0).max() > 1e-6:
            raise SceneError(
                f"{beam.interpolation.path}: straight beams (BeamInterpolation's default) whose"
                " frames' x axes are not along their edges; give straight=False to rest at the"
                " frames as they are"
            )

    clamped, held, loads, forces, masses = [], [], [], [], []
    rest = np.vstack([beam.points, Rotation.from_matrix(beam.frames @ rods.AXES).as_rotvec()])
    for obj in node.objects:
        if obj.type in FIXED:
            if _flag_on(obj, "fixAll"):
                clamped += list(range(n))
            else:
                clamped += _indices(obj, "indices", n, np.array([0])).tolist()
        elif obj.type in PARTIAL:
            flags = rods._flags(obj)
            for k in _indices(obj, "indices", n, None):
                held += [3 * int(k) + a for a in range(3) if flags[a]]
                held += [3 * (n + int(k)) + a for a in range(3) if flags[3 + a]]
        elif obj.type == "RestShapeSpringsForceField":
            external = obj.attrs.get("external_rest_shape", obj.attrs.get("mstate", ""))
            target = builder.link(node, str(external)) if external else None
            if target is not None and target is not beam.dofs:
                raise SceneError(
                    f"{obj.path}: springs to another MechanicalObject's shape ({target.path});"
                    " Pliant reads a beam's springs to its own rest shape"
                )
            points = _indices(obj, "points", n, None)
            k = float(_numbers(obj, "stiffness", [1.0])[0])
            k_turn = float(_numbers(obj, "angularStiffness", [0.0])[0])
            if k > 0:
                loads.append(RestShapeSprings(points, rest, k))
            if k_turn > 0:
                loads.append(RotationSprings(points + n, rest, k_turn))
        elif obj.type == "ConstantForceField":
            load = NodalForces(np.arange(2 * n), np.zeros((2 * n, 3)))
            loads.append(load)
            forces.append((obj, load, np.arange(n)))
        elif obj.type == "UniformMass":
            masses += _point_masses(obj, builder, n)
    kind, damping = builder._ode_solver(node)
    density = _per_edge(beam.forcefield, "massDensity", 1.0, m)
    if not _flag_on(beam.forcefield, "computeMass", default=True):
        density[:] = 0.0
    if not density.any() and not masses:
        kind, gravity = "static", np.zeros(3)  # no mass in SOFA: its implicit step is static
        density[:] = 1.0
    try:
        body = RodBody(
            beam.points,
            section,
            material,
            densities=np.maximum(density, 1e-12 * max(float(density.max()), 1.0)),
            elements=None if polyline else edges,
            frames=beam.frames @ rods.AXES,
            young_moduli=young,
            clamped=sorted(set(clamped)),
            held_dofs=held,
            point_masses=masses,
            loads=loads,
            gravity=gravity,
            rayleigh_mass=damping[0],
            rayleigh_stiffness=damping[1],
        )
    except ModelError as exc:
        raise SceneError(f"{path.name}: {beam.dofs.path}: {exc}") from exc
    if straight:
        body.set_rest_curvature(np.zeros((body.n_elements, 3)))
    data = BeamData(beam, body, forces)
    data.apply_forces()
    rod = rods._Rod(None, None, None, beam.dofs, beam.dofs, np.zeros(2), np.zeros(n))
    contacts = rods._contacts(builder, rod, body)
    return Model(body, contacts=contacts, name=path.stem), dt, kind, data
