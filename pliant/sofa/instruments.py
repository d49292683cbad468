"""BeamAdapter's interventional-radiology instruments, read into a Pliant
:class:`~pliant.fem.instruments.CombinedInstrument` (SofaGym's CatheterBeam and CTR).

What is read (the mechanics and their departures from BeamAdapter are in
:mod:`pliant.fem.instruments`):

* each ``WireRestShape`` (procedural: ``length``, ``straightLength``, ``spireDiameter``,
  ``spireHeight``, ``densityOfBeams``, ``keyPoints``, ``youngModulus``,
  ``youngModulusExtremity``, ``poissonRatio``);
* the combined instrument's node: its ``InterventionalRadiologyController`` (``instruments``
  naming its ``WireBeamInterpolation`` s, ``xtip``, ``rotationInstrument``, ``startingPos``,
  ``speed``, ``controlledInstrument``, ``threshold``), its Rigid3 ``MechanicalObject`` (as many
  nodes as its ``RegularGridTopology``'s nx ny nz, else its positions), each
  ``WireBeamInterpolation`` (``WireRestShape`` link, ``radius``) and the
  ``AdaptiveBeamForceFieldAndMass`` whose ``interpolation`` names it (``massDensity``), its
  ``EulerImplicitSolver``'s Rayleigh damping, the ``RestShapeSpringsForceField`` on the
  controller's ``indexFirstNode`` (``stiffness``, ``angularStiffness``). The
  ``FixedConstraint`` there is the controller's (it holds the nodes not deployed);
  ``BTDLinearSolver`` is a linear solver (Pliant's is exact);
* contact: where the instrument's node carries collision models (the
  ``MultiAdaptiveBeamMapping`` 's points and lines) and the scene detects collisions, its
  deployed nodes (not those waiting behind the entry: ``Contacts.resting``) collide with the
  scene's static obstacles (``TriangleCollisionModel`` with
  ``simulated=False moving=False``) at the intersection's ``contactDistance``, the
  ``alarmDistance`` as margin. Departure: BeamAdapter collides points and segments sampled
  along the beams (``numEdgesCollis``); Pliant collides the nodes;
* ``AdaptiveBeamMapping`` and ``Edge2QuadTopologicalMapping`` (the instruments' drawn tubes)
  and the quad topologies under them are visual: accepted and not computed.

Each step, before it: the controller's ``xtip`` and ``rotationInstrument`` as a script left
them (SofaGym's actions write them), advanced by ``speed`` on the controlled instrument,
deploy the nodes; after it: the nodes' poses into the MechanicalObject (the waiting ones at
``startingPos``), the clamped ``xtip`` and ``indexFirstNode`` into the controller, the
deployed nodes into the collision node's MechanicalObject.
"""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING

import numpy as np
from scipy.spatial.transform import Rotation

from pliant.constraints.base import EmbeddedPoints
from pliant.constraints.contact import Contacts
from pliant.errors import ContactError, ModelError
from pliant.fem.instruments import CombinedInstrument, Instrument, RestShape
from pliant.fem.loads import NodalForces
from pliant.geometry.collision import TriangleSurface
from pliant.model import Model, State
from pliant.sofa import rods
from pliant.sofa.components import is_visual
from pliant.sofa.tree import SceneError, SceneNode, SceneObject, data_value, field_numbers

if TYPE_CHECKING:
    from pliant.sofa.loader import _Builder

REST_SHAPE = "WireRestShape"
INTERPOLATION = "WireBeamInterpolation"
FORCE_FIELD = "AdaptiveBeamForceFieldAndMass"
CONTROLLER = "InterventionalRadiologyController"
COMPONENTS = frozenset(
    {
        REST_SHAPE,
        INTERPOLATION,
        FORCE_FIELD,
        CONTROLLER,
        "MultiAdaptiveBeamMapping",
        "BTDLinearSolver",
        # the instruments' drawn tubes
        "AdaptiveBeamMapping",
        "Edge2QuadTopologicalMapping",
        "QuadSetTopologyContainer",
        "QuadSetTopologyModifier",
        "QuadSetGeometryAlgorithms",
    }
)


# What the combined instrument's node may hold (beside visual components).
ON_INSTRUMENTS = frozenset(
    {
        "MechanicalObject",
        "RegularGridTopology",
        "EdgeSetTopologyContainer",
        "EdgeSetTopologyModifier",
        "EdgeSetGeometryAlgorithms",
        "EulerImplicitSolver",
        "BTDLinearSolver",
        "SparseLDLSolver",
        "LinearSolverConstraintCorrection",
        "GenericConstraintCorrection",
        INTERPOLATION,
        FORCE_FIELD,
        CONTROLLER,
        "FixedConstraint",
        "FixedProjectiveConstraint",
        "RestShapeSpringsForceField",
        "ConstantForceField",
    }
)


def has_instruments(root: SceneNode) -> bool:
    """Whether the scene deploys BeamAdapter instruments (a controller or a WireRestShape)."""
    return any(o.type in (REST_SHAPE, CONTROLLER) for n in root.walk() for o in n.objects)


def _numbers(obj: SceneObject, key: str, default) -> np.ndarray:
    try:
        values = np.asarray(field_numbers(obj, key, default), dtype=float).reshape(-1)
    except (TypeError, ValueError) as exc:
        raise SceneError(f"{obj.path}.{key}: numbers expected ({exc})") from exc
    if not np.all(np.isfinite(values)):
        raise SceneError(f"{obj.path}.{key}: finite numbers expected")
    return values


def _number(obj: SceneObject, key: str, default: float) -> float:
    values = _numbers(obj, key, [default])
    return float(values[0]) if values.size else default


def _rest_shape(obj: SceneObject) -> RestShape:
    if str(obj.attrs.get("isAProceduralShape", "1")).strip().lower() in ("0", "false"):
        raise SceneError(f"{obj.path}: a rest shape from a mesh (isAProceduralShape=0)")
    try:
        return RestShape(
            _number(obj, "length", 1.0),
            straight_length=_number(obj, "straightLength", 0.0),
            spire_diameter=_number(obj, "spireDiameter", 0.1),
            spire_height=_number(obj, "spireHeight", 0.01),
            young=_number(obj, "youngModulus", 5000.0),
            young_extremity=_number(obj, "youngModulusExtremity", 3000.0),
            poisson=_number(obj, "poissonRatio", 0.49),
            key_points=tuple(_numbers(obj, "keyPoints", [])),
            density=tuple(int(d) for d in _numbers(obj, "densityOfBeams", [])),
        )
    except ModelError as exc:
        raise SceneError(f"{obj.path}: {exc}") from exc


def _names(value) -> list[str]:
    if isinstance(value, str):
        return [v.strip("'\" ") for v in value.replace(",", " ").strip("[]").split() if v]
    return [str(v) for v in value]


def _instruments(builder: _Builder, controller: SceneObject) -> list[Instrument]:
    node = controller.node
    interpolations = {o.name: o for o in node.objects if o.type == INTERPOLATION}
    names = _names(controller.attrs.get("instruments", [])) or list(interpolations)
    fields = {
        str(o.attrs.get("interpolation", "")).lstrip("@").split("/")[-1]: o
        for o in node.objects
        if o.type == FORCE_FIELD
    }
    found = []
    for name in names:
        interpolation = interpolations.get(name.split("/")[-1])
        if interpolation is None:
            raise SceneError(f"{controller.path}.instruments: no WireBeamInterpolation {name!r}")
        link = interpolation.attrs.get(REST_SHAPE)
        shape = builder.link(node, str(link)) if isinstance(link, str) else None
        if shape is None or shape.type != REST_SHAPE:
            raise SceneError(f"{interpolation.path}.WireRestShape: {link!r} names no WireRestShape")
        field = fields.get(interpolation.name)
        if field is None:
            raise SceneError(
                f"{interpolation.path}: no AdaptiveBeamForceFieldAndMass with interpolation"
                f" '@{interpolation.name}' beside it"
            )
        try:
            found.append(
                Instrument(
                    _rest_shape(shape),
                    radius=_number(interpolation, "radius", 1.0),
                    mass_density=_number(field, "massDensity", 1.0),
                    name=interpolation.name,
                )
            )
        except ModelError as exc:
            raise SceneError(f"{interpolation.path}: {exc}") from exc
    return found


def _per_instrument(controller: SceneObject, key: str, count: int) -> np.ndarray:
    values = _numbers(controller, key, [])
    out = np.zeros(count)
    out[: min(count, values.size)] = values[:count]
    return out


def _force_field(obj: SceneObject, count: int) -> NodalForces:
    """A Rigid3 ConstantForceField on the combined instrument's nodes: its ``forces`` (one
    per index) or ``force`` (on each), force and moment, as constants."""
    indices = _numbers(obj, "indices", [count - 1]).astype(np.int64)
    if indices.size == 0 or indices.min() < 0 or indices.max() >= count:
        raise SceneError(f"{obj.path}.indices: nodes in [0, {count}) expected")
    values = _numbers(obj, "forces", _numbers(obj, "force", []).tolist())
    if values.size not in (6, 6 * indices.size):
        raise SceneError(f"{obj.path}: six values (force, moment) per index expected")
    values = np.broadcast_to(values.reshape(-1, 6), (indices.size, 6))
    return NodalForces(
        np.concatenate([indices, count + indices]), np.vstack([values[:, :3], values[:, 3:]])
    )


class InstrumentData:
    """The controller's inputs and the nodes' outputs in the scene's data, read before and
    written after each step (a :class:`pliant.sofa.loader.SofaScene` hook)."""

    def __init__(self, combined, controller, dofs, collision, dt: float, contacts=None) -> None:
        self.combined, self.controller, self.dofs = combined, controller, dofs
        self.collision, self.dt, self.contacts = collision, dt, contacts

    def commands(self) -> tuple[np.ndarray, np.ndarray]:
        count = len(self.combined.instruments)
        tips = _per_instrument(self.controller, "xtip", count)
        turns = _per_instrument(self.controller, "rotationInstrument", count)
        speed = _number(self.controller, "speed", 0.0)
        if speed > 0:
            index = int(_number(self.controller, "controlledInstrument", 0.0))
            tips[index if 0 <= index < count else 0] += speed * self.dt
        return tips, turns

    def read(self, state: State) -> State:
        tips, turns = self.commands()
        x, v = self.combined.deploy(state.positions, state.velocities, tips, turns)
        self.rest_waiting()
        return dataclasses.replace(state, positions=x, velocities=v)

    def rest_waiting(self) -> None:
        """The nodes waiting behind the entry do not collide."""
        if self.contacts is not None:
            self.contacts.resting = np.arange(self.combined.n) < self.combined.first

    def write(self, state: State) -> None:
        combined = self.combined
        n = combined.n
        poses = combined.poses(state.positions)
        self.dofs.attrs["position"] = _frozen(poses)
        velocity = np.hstack([state.velocities[:n], state.velocities[n:]])
        velocity[: combined.first] = 0.0
        self.dofs.attrs["velocity"] = _frozen(velocity)
        self.controller.attrs["xtip"] = np.array(combined.tips, dtype=float)
        self.controller.attrs["rotationInstrument"] = np.array(combined.rotations, dtype=float)
        self.controller.attrs["indexFirstNode"] = int(combined.first)
        if self.collision is not None:
            self.collision.attrs["position"] = _frozen(poses[combined.first :, :3])


def _frozen(values) -> np.ndarray:
    array = np.array(values, dtype=float)
    array.flags.writeable = False
    return array


def instrument_model(builder: _Builder) -> tuple[Model, float, str, InstrumentData]:
    """The scene's model, its combined instrument as the body (see the module text); the
    root's time step, the solver kind and the data hook around each step."""
    root, path = builder.root, builder.path
    controllers = [o for n in root.walk() for o in n.objects if o.type == CONTROLLER]
    if len(controllers) != 1:
        raise SceneError(
            f"{path.name}: Pliant deploys instruments through one"
            f" InterventionalRadiologyController, got {len(controllers)}"
        )
    controller = controllers[0]
    node = controller.node
    dt, gravity = rods.alone(builder, "instruments")
    dofs = builder._one(node, {"MechanicalObject"}, "MechanicalObjects")
    template = "" if dofs is None else str(dofs.attrs.get("template", ""))
    if not template.startswith("Rigid3"):
        raise SceneError(f"{node.path}: the combined instrument needs a Rigid3 MechanicalObject")
    grid = builder._one(node, {"RegularGridTopology"}, "grid topologies")
    if grid is not None:
        count = int(np.prod([_number(grid, k, 2.0) for k in ("nx", "ny", "nz")]))
    else:
        count = np.asarray(data_value(dofs.attrs.get("position", [])), float).size // 7
    if count < 2:
        raise SceneError(f"{dofs.path}: the combined instrument needs 2 nodes at least")
    instruments = _instruments(builder, controller)
    start = _numbers(controller, "startingPos", [0, 0, 0, 0, 0, 0, 1])
    if start.size != 7 or np.linalg.norm(start[3:]) == 0:
        raise SceneError(f"{controller.path}.startingPos: a Rigid3 pose (7 values) expected")
    start_pose = (start[:3], Rotation.from_quat(start[3:]).as_matrix())
    springs = (0.0, 0.0)
    for obj in node.objects:
        if obj.type == "RestShapeSpringsForceField":
            k = _number(obj, "stiffness", 1.0)
            springs = (k, _number(obj, "angularStiffness", k))
    unread = [
        f"{o.type} (at {node.path})"
        for o in node.objects
        if o.type not in ON_INSTRUMENTS and not is_visual(o.type)
    ]
    if unread:
        raise SceneError(
            f"{path.name}: on the combined instrument Pliant reads "
            + ", ".join(sorted(ON_INSTRUMENTS))
            + "; not "
            + "; ".join(unread)
        )
    loads = [_force_field(obj, count) for obj in node.objects if obj.type == "ConstantForceField"]
    kind, damping = builder._ode_solver(node)
    if kind != "dynamic":
        raise SceneError(f"{node.path}: instruments are deployed with an EulerImplicitSolver")
    count_tips = len(instruments)
    tips = _per_instrument(controller, "xtip", count_tips)
    turns = _per_instrument(controller, "rotationInstrument", count_tips)
    try:
        combined = CombinedInstrument(
            instruments,
            count,
            start_pose,
            base_stiffness=springs,
            gravity=gravity,
            rayleigh_mass=damping[0],
            rayleigh_stiffness=damping[1],
            threshold=_number(controller, "threshold", 0.01),
            loads=loads,
        )
        combined.start_state(tips, turns)
    except ModelError as exc:
        raise SceneError(f"{path.name}: {node.path}: {exc}") from exc
    collision = None
    for child in node.children:
        if any(o.type == "MultiAdaptiveBeamMapping" for o in child.objects):
            collision = builder._one(child, {"MechanicalObject"}, "MechanicalObjects")
    contacts = _contacts(builder, node, combined)
    data = InstrumentData(combined, controller, dofs, collision, dt, contacts)
    data.rest_waiting()
    model = Model(combined.body, contacts=contacts, name=path.stem)
    return model, dt, kind, data


def _contacts(builder: _Builder, node: SceneNode, combined) -> Contacts | None:
    """The instrument's nodes against the scene's static obstacles."""
    mine = {id(n) for n in node.walk()}
    collides = any(o.type.endswith("CollisionModel") for n in node.walk() for o in n.objects)
    if not collides or not builder._detects():
        return None
    obstacles = []
    for other in builder.root.walk():
        if id(other) in mine or not any(o.type.endswith("CollisionModel") for o in other.objects):
            continue
        dofs = builder._one(other, {"MechanicalObject"}, "MechanicalObjects")
        try:
            obstacles.append(builder._obstacle(other))
        except ContactError:  # an open surface (a vessel phantom): proximity on either side
            if dofs is None:
                raise
            surface = TriangleSurface(builder._positions(other, dofs), builder._faces(other))
            obstacles.append(surface)
        if dofs is not None and builder._rigid_dofs(other.parent) is None:
            # as SOFA's MechanicalObject holds them after its init (scripts read them)
            dofs.attrs["position"] = _frozen(builder._positions(other, dofs))
            for key in ("scale", "scale3d", "rx", "ry", "rz", "rotation", "translation", "dx"):
                dofs.attrs.pop(key, None)
    if not obstacles:
        return None
    proximity = next(
        o for n in builder.root.walk() for o in n.objects if o.type in builder.intersections
    )
    return Contacts(
        obstacles,
        friction=builder._friction(),
        margin=_number(proximity, "alarmDistance", 1.0),
        points=EmbeddedPoints.at_nodes(np.arange(combined.n)),
        thickness=_number(proximity, "contactDistance", 0.5),
    )
