"""Cosserat rods of SOFA's Cosserat plugin, read into a Pliant :class:`~pliant.fem.rod.RodBody`.

SOFA's rod (as SofaGym's ``createCosserat`` builds it, :mod:`pliant.sofa.prefabs.sofagym`):

* a ``BeamHookeLawForceField`` on a Vec3 MechanicalObject of strains, one per section: the
  torsion and the two bendings per unit length of the section (local x along the rod, y and
  z across), with the moment K (strain - rest strain) times the section's ``length``, K =
  diag(G J, E Iy, E Iz); circular (``radius``, ``innerRadius``) or rectangular (``lengthY``,
  ``lengthZ``) section, J = Iy + Iz, G = E / (2 (1 + ``poissonRatio``));
* a ``DiscreteCosseratMapping`` from the strains (``input1``) and a Rigid3 base
  (``input2``) to Rigid3 frames (``output``) at the curvilinear abscissas
  ``curv_abs_output``; the sections run between the abscissas ``curv_abs_input``. At rest
  the frames follow the base frame's x axis, curved by the initial strains.

Pliant's rod has a node at each distinct frame abscissa, its directors d1, d2, d3 the frame's
y, z and x axes, and SOFA's stiffness: bending E Iy, E Iz and torsion G J. SOFA's strain is
one per section: the elements of a section are tied to the same curvature and twist
(:class:`pliant.fem.rod.SectionTies`, a stiff penalty), so that a section bends only into
an arc or a helix as SOFA's does (SofaGym's stems have one section: under an end load such a
rod deflects F L^3 / (4 E I), not the elastica's F L^3 / (3 E I)). An element straddling two
sections belongs to the one holding its middle. Departure: Pliant's rod also stretches and
shears, with the stiffness E A and G A that SOFA's inextensible and unshearable rod has as
constraints (small for a slender rod).

What the rod carries:

* its mass: a ``UniformMass`` on the frames (``totalMass``, or ``vertexMass`` per frame),
  spread along the rod (SOFA puts it on the frames); a rod with no mass of its own but
  carrying solids gets a negligible one (:data:`ROD_MASS_SHARE`: Pliant's nodes need one);
  a rod with no mass anywhere is solved statically, as SOFA's implicit step is then;
* its base: held by a ``FixedConstraint`` (a clamp), by ``PartialFixedConstraint``'s
  directions, by ``RestShapeSpringsForceField``'s springs (``stiffness`` on its position,
  ``angularStiffness`` on its turn from rest, :class:`pliant.fem.loads.RotationSprings`),
  or free; a base that is a rigid body with
  a mass (SofaGym's cart) is built into the rod's first node: its mass, and its inertia
  (isotropic, the mean of its principal moments);
* solids welded to a frame by a Rigid3 ``BilateralInteractionConstraint`` (position and
  angle) with their centre on it: their mass and inertia on that frame's node;
* ``ConstantForceField`` forces and moments on the frames or the base (``force``,
  ``forces``, ``totalForce``; read again before each step, as a controller sets them);
* contact: collision models on the frames (``addEdgeCollision``'s points and lines, points
  carried by a frame) collide the rod's nodes with the scene's static obstacles, at the
  intersection's ``contactDistance`` (as SOFA's lines, which have no thickness; a carried
  point collides at its frame's node, the lines between the nodes not at all).

A rod with no mass, no solid, no load and no contact (SofaGym's drawn ``Path``) never moves in
SOFA: Pliant leaves it out of the model, its data at rest (a scene whose rods are all such
is read without them). Written back after each step: the frames, the base's and the welded
solids' poses and velocities, the strains (each section's mean), the points the frames carry.
A controller that writes the strains' ``rest_position`` sets the rod's rest curvature
(:meth:`pliant.fem.rod.RodBody.set_rest_curvature`); one that writes the base's
``position`` (SofaGym's CartStemContact moves its cart so) moves the rod's first node.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
import scipy.linalg
from scipy.spatial.transform import Rotation

from pliant.constraints.base import EmbeddedPoints
from pliant.constraints.contact import Contacts
from pliant.errors import ModelError
from pliant.fem.loads import NodalForces, RestShapeSprings, RotationSprings
from pliant.fem.material import Material
from pliant.fem.rod import RodBody, RodSection
from pliant.model import Model, State
from pliant.sofa.rigids import _rigid_mass_values
from pliant.sofa.tree import SceneError, SceneNode, SceneObject, data_value, field_numbers

if TYPE_CHECKING:
    from pliant.sofa.loader import _Builder

LAW = "BeamHookeLawForceField"
MAPPING = "DiscreteCosseratMapping"
WELD = "BilateralInteractionConstraint"
COMPONENTS = frozenset({LAW, MAPPING, WELD})
# SOFA's frame (x along the rod) as Pliant's directors: R_pliant = R_sofa @ AXES (d1 = y,
# d2 = z, d3 = x); Pliant's curvature (d1, d2, d3) is SOFA's strain (x, y, z) reordered.
AXES = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
TO_PLIANT = [1, 2, 0]
TO_SOFA = [2, 0, 1]
# A rod with no mass of its own carrying solids gets this share of E I dt^2 / L^3 (the mass
# whose inertia over a step weighs as much as its bending stiffness), spread along it.
ROD_MASS_SHARE = 1e-6
# Cosserat's BeamHookeLawForceField defaults.
DEFAULT_YOUNG, DEFAULT_POISSON, DEFAULT_RADIUS = 1.0e9, 0.45, 1.0


def has_rods(root: SceneNode) -> bool:
    """Whether the scene holds a Cosserat rod (a BeamHookeLawForceField)."""
    return any(o.type == LAW for n in root.walk() for o in n.objects)


@dataclass
class _Rod:
    """One rod of the scene: its components and its layout."""

    law: SceneObject
    strains: SceneObject  # Vec3 MechanicalObject, one strain per section
    mapping: SceneObject
    frames: SceneObject  # Rigid3 MechanicalObject of the frames
    base: SceneObject  # Rigid3 MechanicalObject of the base
    sections: np.ndarray  # (S + 1,) abscissas of the sections' ends
    abscissas: np.ndarray  # (F,) of the frames
    nodes: np.ndarray = field(default_factory=lambda: np.zeros(0))  # (N,) distinct abscissas
    frame_node: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))  # (F,)
    welded: list = field(default_factory=list)  # (MechanicalObject, node, its rest pose)


def _objects(node: SceneNode, kind: str) -> list[SceneObject]:
    return [o for o in node.objects if o.type == kind]


def _numbers(obj: SceneObject, key: str, default) -> np.ndarray:
    return np.asarray(field_numbers(obj, key, default), dtype=float).reshape(-1)


def _linked(builder: _Builder, obj: SceneObject, key: str) -> SceneObject:
    value = obj.attrs.get(key)
    found = builder.link(obj.node, str(value)) if isinstance(value, str) else None
    if found is None or found.type != "MechanicalObject":
        raise SceneError(f"{obj.path}.{key}: {value!r} names no MechanicalObject")
    return found


def _read_rod(builder: _Builder, law: SceneObject) -> _Rod:
    strains = builder._one(law.node, {"MechanicalObject"}, "MechanicalObjects")
    if strains is None:
        raise SceneError(f"{law.path}: no MechanicalObject of strains beside it")
    mappings = [
        o
        for n in builder.root.walk()
        for o in _objects(n, MAPPING)
        if str(o.attrs.get("input1", "")).rstrip("/").split("/")[-1] == strains.name
        and _linked(builder, o, "input1") is strains
    ]
    if len(mappings) != 1:
        raise SceneError(
            f"{law.path}: one DiscreteCosseratMapping must map its strains ({strains.path}) to"
            f" frames, got {len(mappings)}"
        )
    mapping = mappings[0]
    sections = _numbers(mapping, "curv_abs_input", [])
    abscissas = _numbers(mapping, "curv_abs_output", [])
    n_strains = len(_strain_values(strains, "position"))
    if sections.size != n_strains + 1 or np.any(np.diff(sections) <= 0):
        raise SceneError(
            f"{mapping.path}.curv_abs_input: {n_strains + 1} increasing abscissas expected (the"
            f" ends of the {n_strains} sections of {strains.path})"
        )
    lengths = _numbers(law, "length", np.diff(sections))
    if lengths.size != n_strains or not np.allclose(lengths, np.diff(sections), rtol=1e-6):
        raise SceneError(
            f"{law.path}.length: the sections' lengths {lengths.tolist()} differ from the"
            f" mapping's abscissas {sections.tolist()}"
        )
    if (
        abscissas.size < 2
        or np.any(np.diff(abscissas) < 0)
        or abscissas[0] < sections[0] - 1e-9 * np.ptp(sections)
        or abscissas[-1] > sections[-1] + 1e-9 * np.ptp(sections)
    ):
        raise SceneError(
            f"{mapping.path}.curv_abs_output: non-decreasing abscissas within the sections'"
            f" [{sections[0]:g}, {sections[-1]:g}] expected"
        )
    rod = _Rod(
        law,
        strains,
        mapping,
        _linked(builder, mapping, "output"),
        _linked(builder, mapping, "input2"),
        sections,
        abscissas,
    )
    tolerance = 1e-9 * np.ptp(sections)
    keep = np.concatenate([[True], np.diff(abscissas) > tolerance])
    rod.nodes = abscissas[keep]
    rod.frame_node = np.cumsum(keep) - 1
    return rod


def _strain_values(strains: SceneObject, key: str) -> np.ndarray:
    raw = strains.attrs.get(key)
    if raw is None and key == "rest_position":
        raw = strains.attrs.get("position")
    values = np.asarray(data_value(raw if raw is not None else []), dtype=float)
    if values.size % 3:
        raise SceneError(f"{strains.path}.{key}: one strain (3 values) per section expected")
    return values.reshape(-1, 3)


def _section_of(rod: _Rod, abscissa: np.ndarray) -> np.ndarray:
    return np.clip(
        np.searchsorted(rod.sections, abscissa, side="right") - 1, 0, len(rod.sections) - 2
    )


def _rest_frames(rod: _Rod, base: tuple[np.ndarray, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """(N, 3) points and (N, 3, 3) SOFA frames at the nodes' abscissas: the base frame
    carried along each section by its initial strain (angular rate, unit speed along x)."""
    strain = _strain_values(rod.strains, "position")
    pose = np.eye(4)
    pose[:3, :3], pose[:3, 3] = base[1], base[0]
    points, frames = [], []
    at, section = rod.sections[0], 0
    for target in rod.nodes:
        while True:
            end = min(target, rod.sections[section + 1])
            twist = np.zeros((4, 4))
            k = strain[section]
            twist[:3, :3] = [[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]]
            twist[0, 3] = 1.0
            pose = pose @ scipy.linalg.expm(twist * (end - at))
            at = end
            if target <= rod.sections[section + 1] or section == len(strain) - 1:
                break
            section += 1
        points.append(pose[:3, 3].copy())
        frames.append(pose[:3, :3].copy())
    return np.array(points), np.array(frames)


def _section(law: SceneObject) -> RodSection:
    return sofa_section(law, lambda key, default: float(_numbers(law, key, [default])[0]))


def sofa_section(obj: SceneObject, value: Callable[[str, float], float]) -> RodSection:
    """A beam's section as SOFA reads it (the Cosserat plugin's BeamHookeLawForceField and
    BeamAdapter's BeamInterpolation alike): ``crossSectionShape`` circular (``radius``,
    ``innerRadius``; J = 2 I) or rectangular (``lengthY``, ``lengthZ``; J = Iy + Iz), each 1
    by default. `value(key, default)` reads one number of `obj`."""
    shape = str(obj.attrs.get("crossSectionShape", "circular")).strip().lower()
    try:
        if shape == "rectangular":
            section = RodSection.rectangle(value("lengthY", 1.0), value("lengthZ", 1.0))
            return dataclasses.replace(section, torsion=sum(section.inertia))
        if shape != "circular":
            raise SceneError(
                f"{obj.path}.crossSectionShape: 'circular' or 'rectangular', got {shape!r}"
            )
        radius, inner = value("radius", DEFAULT_RADIUS), value("innerRadius", 0.0)
        section = RodSection.circle(radius)
    except ModelError as exc:
        raise SceneError(f"{obj.path}: {exc}") from exc
    if inner > 0.0:
        if inner >= radius:
            raise SceneError(f"{obj.path}.innerRadius: smaller than the radius expected")
        i = np.pi * (radius**4 - inner**4) / 4.0
        area = np.pi * (radius**2 - inner**2)
        section = dataclasses.replace(section, area=area, inertia=(i, i), torsion=2.0 * i)
    return section


def _material(law: SceneObject) -> Material:
    if str(law.attrs.get("variantSections", "0")).strip().lower() in ("1", "true"):
        raise SceneError(
            f"{law.path}.variantSections: sections of different materials (not supported)"
        )
    if str(law.attrs.get("useInertiaParams", "0")).strip().lower() in ("1", "true"):
        raise SceneError(f"{law.path}.useInertiaParams: give youngModulus and poissonRatio instead")
    young = float(_numbers(law, "youngModulus", [DEFAULT_YOUNG])[0])
    poisson = float(_numbers(law, "poissonRatio", [DEFAULT_POISSON])[0])
    try:
        return Material(young, poisson)
    except ModelError as exc:
        raise SceneError(f"{law.path}: {exc}") from exc


def _flags(obj: SceneObject) -> np.ndarray:
    flags = _numbers(obj, "fixedDirections", [1, 1, 1, 1, 1, 1])
    if flags.size != 6:
        raise SceneError(f"{obj.path}.fixedDirections: six flags for a Rigid3 point expected")
    return flags.astype(bool)


def _indices(obj: SceneObject, key: str, count: int) -> np.ndarray:
    if key not in obj.attrs:
        return np.arange(count)
    idx = _numbers(obj, key, []).astype(np.int64)
    if idx.size and (idx.min() < 0 or idx.max() >= count):
        raise SceneError(f"{obj.path}.{key}: indices in [0, {count}) expected, got {idx.tolist()}")
    return idx


def _wrenches(obj: SceneObject, count: int) -> tuple[np.ndarray, np.ndarray]:
    """A Rigid3 ConstantForceField's points and their (k, 6) forces and moments: its
    ``forces`` (one per point), else its ``force`` (on each), else its ``totalForce`` (shared),
    whichever is set and not zero (a controller sets ``force`` on SofaGym's cart, created
    with a zero ``totalForce``)."""
    idx = _indices(obj, "indices", count)
    values = np.zeros((1, 6))
    for key in ("forces", "force", "totalForce"):  # the first one set and not zero
        given = np.asarray(data_value(obj.attrs.get(key, [])), dtype=float).reshape(-1)
        if given.size and given.any():
            values = given.reshape(-1, 6) / (max(idx.size, 1) if key == "totalForce" else 1)
            break
    if len(values) not in (1, idx.size) or not np.all(np.isfinite(values)):
        raise SceneError(f"{obj.path}: finite 6-value forces (force and moment) per point expected")
    return idx, np.broadcast_to(values, (idx.size, 6))


def _mass_of(builder: _Builder, node: SceneNode) -> tuple[float, float] | None:
    """A Rigid3 solid's mass and isotropic inertia (mean principal moment), or None."""
    mass = builder._one(node, {"UniformMass"}, "masses")
    if mass is None:
        return None
    values = _rigid_mass_values(builder, mass)
    inertia = values[0] * values[2:].reshape(3, 3)
    return float(values[0]), float(np.trace(inertia) / 3.0)


def _pose(builder: _Builder, dofs: SceneObject, index: int = 0) -> tuple[np.ndarray, np.ndarray]:
    poses = np.asarray(data_value(dofs.attrs.get("position", [0, 0, 0, 0, 0, 0, 1])), float)
    poses = poses.reshape(-1, 7)
    if index >= len(poses):
        raise SceneError(f"{dofs.path}: no frame {index} (it has {len(poses)})")
    position = poses[index, :3] + _numbers(dofs, "translation", [0.0, 0.0, 0.0])
    return position, Rotation.from_quat(poses[index, 3:]).as_matrix()


class RodData:
    """The rod's inputs and outputs in the scene's data, read before and written after each
    step (a :class:`pliant.sofa.loader.SofaScene` hook)."""

    def __init__(self, rod: _Rod, body: RodBody, forces: list) -> None:
        self.rod, self.body, self.forces = rod, body, forces
        self.section_of = _section_of(rod, 0.5 * (rod.nodes[:-1] + rod.nodes[1:]))
        self.rest = _strain_values(rod.strains, "rest_position").copy()
        self.written_base: np.ndarray | None = None
        self.carried: dict = {}  # local points of the MechanicalObjects frames carry

    def read(self, state: State) -> State:
        self.apply_forces()
        rest = _strain_values(self.rod.strains, "rest_position")
        if rest.shape == self.rest.shape and not np.array_equal(rest, self.rest):
            self.rest = rest.copy()
            self.body.set_rest_curvature(rest[self.section_of][:, TO_PLIANT])
        base = np.asarray(data_value(self.rod.base.attrs.get("position")), float).reshape(-1, 7)
        if self.written_base is not None and not np.array_equal(base[0], self.written_base):
            positions = state.positions.copy()  # a script moved the base
            positions[0] = base[0, :3]
            state = dataclasses.replace(state, positions=positions)
        return state

    def apply_forces(self) -> None:
        """The ConstantForceFields' forces and moments (as a controller may have set them)
        into the rod's loads."""
        n = self.body.n_centreline
        for obj, load, points in self.forces:
            values = np.zeros((2 * n, 3))
            idx, wrench = _wrenches(obj, len(points))
            np.add.at(values, points[idx], wrench[:, :3])
            np.add.at(values, n + points[idx], wrench[:, 3:])
            load.values[:] = values

    def write(self, state: State) -> None:
        n, rod = self.body.n_centreline, self.rod
        x, v = state.positions, state.velocities
        sofa = self.body.frames(x) @ AXES.T
        quats = Rotation.from_matrix(sofa).as_quat()
        quats[quats[:, 3] < 0] *= -1.0  # w >= 0, as the scene gives its poses
        poses = np.hstack([x[:n], quats])
        twists = np.hstack([v[:n], v[n:]])
        frames = rod.frame_node
        rod.frames.attrs["position"] = _frozen(poses[frames])
        rod.frames.attrs["velocity"] = _frozen(twists[frames])
        rod.base.attrs["position"] = _frozen(poses[:1])
        rod.base.attrs["velocity"] = _frozen(twists[:1])
        self.written_base = poses[0].copy()
        for dofs, node, rest in rod.welded:
            turned = Rotation.from_matrix(sofa[node] @ rest[1]).as_quat()
            turned *= -1.0 if turned[3] < 0 else 1.0
            dofs.attrs["position"] = _frozen(np.concatenate([x[node], turned])[None])
            dofs.attrs["velocity"] = _frozen(twists[node][None])
        turns = self.body.frames(x)
        lengths = np.diff(rod.nodes)
        bends = (
            np.array(
                [
                    Rotation.from_matrix(a.T @ b).as_rotvec()
                    for a, b in zip(turns[:-1], turns[1:], strict=True)
                ]
            )
            / lengths[:, None]
        )
        strains = np.zeros((len(rod.sections) - 1, 3))
        weight = np.zeros(len(strains))
        np.add.at(strains, self.section_of, bends[:, TO_SOFA] * lengths[:, None])
        np.add.at(weight, self.section_of, lengths)
        strains[weight > 0] /= weight[weight > 0, None]
        rod.strains.attrs["position"] = _frozen(strains)
        write_carried(rod.frames.node, x[:n], sofa, frames, self.carried)


def write_carried(
    node: SceneNode, points: np.ndarray, sofa: np.ndarray, frame_node: np.ndarray, cache: dict
) -> None:
    """The points carried by a rod's frames (children of the frames' `node` with an
    IdentityMapping or a RigidMapping), placed at the rod's nodes `points` and SOFA frames
    `sofa`; frame k of the MechanicalObject is node `frame_node[k]`. `cache` keeps each
    RigidMapping's points in its frame, read once."""
    for child in node.children:
        dofs = child.getMechanicalState()
        if dofs is None:
            continue
        if _objects(child, "IdentityMapping"):
            dofs.attrs["position"] = _frozen(points[frame_node])
        for mapping in _objects(child, "RigidMapping"):
            at = frame_node[int(_numbers(mapping, "index", [0])[0])]
            local = cache.setdefault(id(dofs), _local_points(dofs))
            dofs.attrs["position"] = _frozen(points[at] + local @ sofa[at].T)


def _local_points(dofs: SceneObject) -> np.ndarray:
    """A RigidMapping's points in its frame: the MechanicalObject's positions (one point at
    the origin when it gives none), shifted by its ``translation``."""
    given = np.asarray(data_value(dofs.attrs.get("position", [])), dtype=float).reshape(-1, 3)
    points = given if len(given) else np.zeros((1, 3))
    return points + _numbers(dofs, "translation", [0.0, 0.0, 0.0])


def _frozen(values) -> np.ndarray:
    array = np.array(values, dtype=float)
    array.flags.writeable = False
    return array


def _active(builder: _Builder, rod: _Rod) -> bool:
    """Whether the rod can move: a mass, a solid it carries, a load or contact."""
    here = [o for n in (rod.frames.node, rod.base.node) for o in n.objects]
    if any(o.type in ("UniformMass", "ConstantForceField") for o in here):
        return True
    if any(
        any(
            builder.link(o.node, str(o.attrs.get(k, ""))) is rod.frames
            for k in ("object1", "object2")
        )
        for n in builder.root.walk()
        for o in _objects(n, WELD)
    ):
        return True
    collides = any(
        o.type.endswith("CollisionModel") for c in rod.frames.node.walk() for o in c.objects
    )
    return collides and builder._detects()


def moving_rods(builder: _Builder) -> bool:
    """Whether the scene has a Cosserat rod that moves; the rods that never move are taken
    out of the tree the model is read from (a script still reaches them by their names)."""
    rods = [_read_rod(builder, law) for n in builder.root.walk() for law in _objects(n, LAW)]
    still = [r for r in rods if not _active(builder, r)]
    if len(still) < len(rods):
        return True
    for rod in still:
        nodes = [rod.strains.node, rod.frames.node, rod.base.node]
        top = rod.strains.node.parent
        if top is not None and all(n is top or n.parent is top for n in nodes[::2]):
            nodes = [top]  # createCosserat's node: the rod's base, strains and frames
        for node in nodes:
            parent = node.parent
            if parent is not None and node in parent.children:
                parent.children.remove(node)
                parent.extras[str(node.name)] = node
    return False


def alone(builder: _Builder, body: str) -> tuple[float, np.ndarray]:
    """The root's time step and gravity for a scene whose one body is `body` (a rod, a beam,
    instruments); a SceneError where a deformable body stands beside it (Pliant's model has
    one body) or actuators and effectors act (on a tetrahedral body's points only)."""
    path = builder.path
    if builder._deformable_nodes():
        raise SceneError(
            f"{path.name}: {body} beside a deformable body"
            f" ({builder._deformable_nodes()[0].path}); Pliant's model has one body"
        )
    acting = [
        f"{o.type} (at {n.path})"
        for n in builder.root.walk()
        for o in n.objects
        if o.type in builder.point_constraints
    ]
    if acting:
        raise SceneError(
            f"{path.name}: actuators and effectors act on a tetrahedral body's points, not on"
            f" {body}: " + "; ".join(acting)
        )
    return builder._scene_time()


def rod_model(builder: _Builder) -> tuple[Model, float, str, RodData]:
    """The scene's model, its one moving Cosserat rod as the body (see the module text); the
    root's time step, the solver kind ("dynamic", or "static" for a rod with no mass) and the
    rod's data to read and write around each step."""
    root, path = builder.root, builder.path
    rods = [_read_rod(builder, law) for n in root.walk() for law in _objects(n, LAW)]
    moving = [r for r in rods if _active(builder, r)]
    if len(moving) != 1:
        names = ", ".join(r.strains.node.path for r in (moving or rods))
        raise SceneError(
            f"{path.name}: Pliant simulates one moving Cosserat rod (the model's body), got"
            f" {len(moving)} ({names})"
        )
    rod = moving[0]
    dt, gravity = alone(builder, "a Cosserat rod")
    base_pose = _pose(builder, rod.base)
    points, sofa_frames = _rest_frames(rod, base_pose)
    n = len(points)
    clamped, held, masses, loads, forces = [], [], [], [], []
    # The base: held, on springs, carrying a mass, loaded.
    base_node = rod.base.node
    for obj in base_node.objects:
        if obj.type in ("FixedConstraint", "FixedProjectiveConstraint"):
            clamped.append(0)
        elif obj.type in ("PartialFixedConstraint", "PartialFixedProjectiveConstraint"):
            flags = _flags(obj)
            held += [3 * 0 + a for a in range(3) if flags[a]]
            held += [3 * n + a for a in range(3) if flags[3 + a]]
        elif obj.type == "RestShapeSpringsForceField":
            k = float(_numbers(obj, "stiffness", [1.0])[0])
            k_turn = float(_numbers(obj, "angularStiffness", [k])[0])
            rest = np.vstack([points, np.zeros((n, 3))])
            if k > 0:
                loads.append(RestShapeSprings([0], rest, k))
            if k_turn > 0:
                rest_turn = np.vstack(
                    [points, Rotation.from_matrix(sofa_frames @ AXES).as_rotvec()]
                )
                loads.append(RotationSprings([n], rest_turn, k_turn))
    solid = _mass_of(builder, base_node)
    if solid is not None:
        masses.append((0, *solid))
    carried = [(base_node, np.zeros(1, np.int64))]
    carried.append((rod.frames.node, rod.frame_node))
    for node, at in carried:
        for obj in _objects(node, "ConstantForceField"):
            load = NodalForces(np.arange(2 * n), np.zeros((2 * n, 3)))
            loads.append(load)
            forces.append((obj, load, at))
    for obj in rod.frames.node.objects:
        if obj.type in ("FixedConstraint", "FixedProjectiveConstraint"):
            clamped += rod.frame_node[_indices(obj, "indices", len(rod.frame_node))].tolist()
    # Solids welded to frames.
    for obj in (o for m in root.walk() for o in _objects(m, WELD)):
        ends = [_linked(builder, obj, k) for k in ("object1", "object2")]
        if rod.frames not in ends:
            raise SceneError(
                f"{obj.path}: Pliant reads a BilateralInteractionConstraint between a rod's"
                " frames and a solid only"
            )
        other = ends[1] if ends[0] is rod.frames else ends[0]
        keys = (
            ("first_point", "second_point") if ends[0] is other else ("second_point", "first_point")
        )
        frame = int(_numbers(obj, keys[1], [0])[0])
        if not 0 <= frame < len(rod.frame_node):
            raise SceneError(f"{obj.path}.{keys[1]}: no frame {frame} on {rod.frames.path}")
        node = int(rod.frame_node[frame])
        centre, turn = _pose(builder, other, int(_numbers(obj, keys[0], [0])[0]))
        if np.linalg.norm(centre - points[node]) > 1e-6 * np.ptp(rod.sections):
            raise SceneError(
                f"{obj.path}: the solid {other.path} is welded at {centre.tolist()}, away from"
                f" frame {frame} at {points[node].tolist()}; Pliant welds solids centred on a frame"
            )
        solid = _mass_of(builder, other.node)
        if solid is None:
            raise SceneError(f"{other.node.path}: a welded solid needs a mass (a UniformMass)")
        masses.append((node, *solid))
        rod.welded.append((other, node, (centre, sofa_frames[node].T @ turn)))
    # Moving solids the rod does not carry: SOFA moves them, Pliant's model has none here.
    carried = {id(rod.base.node)} | {id(w[0].node) for w in rod.welded}
    loose = [
        n.path
        for n in root.walk()
        if id(n) not in carried
        and builder._is_rigid(n)
        and _objects(n, "UniformMass")
        and not any(o.type in ("FixedConstraint", "FixedProjectiveConstraint") for o in n.objects)
    ]
    if loose:
        raise SceneError(
            f"{path.name}: moving rigid bodies beside a Cosserat rod are not supported"
            f" ({', '.join(loose)}); Pliant reads solids welded to the rod or carrying its base"
        )
    # The rod's own mass.
    own = builder._one(rod.frames.node, {"UniformMass"}, "masses")
    kind, damping = builder._ode_solver(rod.strains.node)
    if own is not None:
        if "totalMass" in own.attrs:
            total = float(_numbers(own, "totalMass", [1.0])[0])
        else:
            total = len(rod.abscissas) * float(_numbers(own, "vertexMass", [1.0])[0])
    elif masses:  # mass enough for the step, too little to weigh: its sag ~1e-6 g dt^2
        section = _section(rod.law)
        stiffness = _material(rod.law).young_modulus * max(section.inertia)
        total = ROD_MASS_SHARE * stiffness * dt**2 / np.ptp(rod.nodes) ** 3
    else:  # none in SOFA: solved statically, weightless
        total, kind, gravity = 1.0, "static", np.zeros(3)
    try:
        body = RodBody(
            points,
            _section(rod.law),
            _material(rod.law),
            total_mass=total,
            frames=sofa_frames @ AXES,
            clamped=sorted(set(clamped)),
            held_dofs=held,
            point_masses=masses,
            loads=loads,
            gravity=gravity,
            rayleigh_mass=damping[0],
            rayleigh_stiffness=damping[1],
            sections=_section_of(rod, 0.5 * (rod.nodes[:-1] + rod.nodes[1:])),
        )
    except ModelError as exc:
        raise SceneError(f"{path.name}: {rod.strains.node.path}: {exc}") from exc
    rest = _strain_values(rod.strains, "rest_position")
    data = RodData(rod, body, forces)
    data.apply_forces()
    if not np.allclose(rest, _strain_values(rod.strains, "position")):
        body.set_rest_curvature(rest[data.section_of][:, TO_PLIANT])
    rod.strains.attrs.setdefault("rest_position", _frozen(rest))
    contacts = _contacts(builder, rod, body)
    return Model(body, contacts=contacts, name=path.stem), dt, kind, data


def _contacts(builder: _Builder, rod: _Rod, body: RodBody) -> Contacts | None:
    """The rod's nodes against the scene's static obstacles, when its frames carry collision
    models and the scene detects collisions."""
    mine = [
        c
        for c in rod.frames.node.walk()
        if any(o.type.endswith("CollisionModel") for o in c.objects)
    ]
    if not mine or not builder._detects():
        return None
    carried = {id(n) for w in rod.welded for n in w[0].node.walk()}
    carried |= {id(n) for n in rod.base.node.walk()}
    carried |= {id(n) for n in rod.frames.node.walk()}
    obstacles = []
    for node in builder.root.walk():
        if id(node) in carried or not any(o.type.endswith("CollisionModel") for o in node.objects):
            continue
        frame = builder._rigid_dofs(node.parent)
        moving = (
            frame is not None
            and builder._is_rigid(node.parent)
            and not any(
                o.type in ("FixedConstraint", "FixedProjectiveConstraint")
                for o in node.parent.objects
            )
        )
        if moving:
            raise SceneError(
                f"{node.path}: a moving rigid body beside a Cosserat rod (not supported)"
            )
        obstacles.append(builder._obstacle(node))
    if not obstacles:
        return None
    proximity = next(
        o for n in builder.root.walk() for o in n.objects if o.type in builder.intersections
    )
    margin = float(_numbers(proximity, "alarmDistance", [1.0])[0])
    return Contacts(
        obstacles,
        friction=builder._friction(),
        margin=margin,
        points=EmbeddedPoints.at_nodes(body.colliding_nodes()),
        thickness=float(_numbers(proximity, "contactDistance", [0.5])[0]),
    )
