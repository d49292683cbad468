"""Scenes of rigid bodies alone (no deformable body), read into a Pliant model without body
(``Model(None, ...)``, stepped by the rigid bodies' scheme, :mod:`pliant.solvers.rigid`).

* Moving rigid bodies: as beside a deformable body (:mod:`pliant.sofa.rigids`): a ``Rigid3``
  MechanicalObject with a ``UniformMass`` and a collision shape, or a particle ball.
* A massless ``Rigid3`` frame held by a ``RestShapeSpringsForceField`` (SofaGym's SimpleMaze:
  the maze's frame, whose ``rest_position`` the actions tilt): a kinematic body at its rest
  pose, the collision models it carries (a ``RigidMapping``) moving with it: a closed
  triangle mesh whose inside is read from its winding number (SimpleMaze's coarse maze has a
  floor of zero thickness, two coincident sheets facing opposite ways, which SOFA's triangle
  proximity holds a ball on; the pseudo-normal of whichever sheet is found first would not).
  SOFA's frame reaches its rest pose in one step (a massless first-order step is a Newton
  step on the springs) less the contact forces over the springs' stiffness, which Pliant
  leaves out.
* ``BilateralInteractionConstraint`` (Vec3): the points ``first_point`` of ``object1`` held
  on the points ``second_point`` of ``object2`` (:class:`~pliant.constraints.rigid_joints.
  BallJoint`); ``SlidingConstraint``: the point ``sliding_point`` of ``object1`` held on the
  line through the points ``axis_1`` and ``axis_2`` of ``object2``
  (:class:`~pliant.constraints.rigid_joints.SlidingJoint`). Each point is one of a
  MechanicalObject carried by a rigid body (a ``RigidMapping``: its positions are in the
  body's frame), or a still one (world positions).
* ``FixedConstraint`` on a body's frame: its velocity held at zero (:class:`~pliant.
  constraints.rigid_joints.AxisLock`); a ``PartialFixedConstraint`` holds components of its
  twist as on any rigid body (``RigidBody(held=...)``, read by :func:`~pliant.sofa.rigids.
  rigid_body`).
* ``RestShapeSpringsForceField`` on a body's frame (``stiffness``, ``angularStiffness``): an
  implicit spring to the frame's ``rest_position`` (:class:`~pliant.constraints.rigid_joints.
  RestSpring`), read again before each step.
* ``ConstantForceField`` on a body's frame: a force and torque in the world
  (:class:`~pliant.fem.rigid.WorldForce`), read again before each step (a controller pushing
  SofaGym's cart sets its ``force``).
* Static collision models: obstacles, as beside a deformable body (a flat one, there the
  infinite plane of its triangles, is here the slab under them); ``alarmDistance`` the
  contact margin, the response's ``mu`` the friction. SOFA's ``contactDistance`` (a
  thickness of the contact) is not used: the rigid bodies touch at their surfaces.
"""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING

import numpy as np
from scipy.spatial.transform import Rotation

from pliant.constraints.contact import Contacts
from pliant.constraints.rigid_joints import AxisLock, BallJoint, RestSpring, SlidingJoint
from pliant.errors import ContactError, ModelError
from pliant.fem.rigid import KinematicBody, RigidBody, WorldForce
from pliant.geometry.collision import Box, Plane, TriangleMesh
from pliant.model import Model, State
from pliant.sofa.rigids import rigid_body
from pliant.sofa.rods import _wrenches
from pliant.sofa.tree import SceneError, SceneNode, SceneObject, data_value, field_numbers

if TYPE_CHECKING:
    from pliant.sofa.loader import _Builder

SLIDING = "SlidingConstraint"
BILATERAL = "BilateralInteractionConstraint"
JOINTS = frozenset({SLIDING, BILATERAL})
FIXED = frozenset({"FixedConstraint", "FixedProjectiveConstraint"})
PARTIAL = frozenset({"PartialFixedConstraint", "PartialFixedProjectiveConstraint"})
SPRINGS = "RestShapeSpringsForceField"


def is_rigid_scene(builder: _Builder) -> bool:
    """A scene of rigid bodies alone: no deformable body, and a moving rigid body."""
    return not builder._deformable_nodes() and any(
        builder._is_rigid(n) and not _spring_frame(builder, n) for n in builder.root.walk()
    )


def _spring_frame(builder: _Builder, node: SceneNode) -> bool:
    """A massless Rigid3 frame held by rest-shape springs (a kinematic body in Pliant)."""
    return (
        builder._rigid_dofs(node) is not None
        and not any(o.type == "UniformMass" for o in node.objects)
        and any(o.type == SPRINGS for o in node.objects)
    )


@dataclasses.dataclass
class _Frame:
    """A spring-held frame: its MechanicalObject and the pose it is at."""

    dofs: SceneObject
    position: np.ndarray
    rotation: np.ndarray

    def pose(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        return self.position, self.rotation

    def read(self) -> None:
        """The pose its springs pull it to: its ``rest_position`` (else its position)."""
        value = self.dofs.attrs.get("rest_position", self.dofs.attrs.get("position"))
        pose = np.asarray(data_value(value), dtype=float).reshape(-1)
        if pose.size < 7 or not np.all(np.isfinite(pose[:7])):
            raise SceneError(f"{self.dofs.path}.rest_position: one finite Rigid3 pose expected")
        self.position = pose[:3].copy()
        self.rotation = Rotation.from_quat(pose[3:7]).as_matrix()


class RigidData:
    """The scene's inputs and outputs of a model of rigid bodies (a
    :class:`pliant.sofa.loader.SofaScene` hook): the ConstantForceFields' forces and the
    spring-held frames' rest poses read before a step, the frames' poses written after it."""

    def __init__(self, forces, frames: list[_Frame], springs=()):
        self.forces, self.frames, self.springs = forces, frames, list(springs)

    def read(self, state: State) -> State:
        for obj, force in self.forces:
            _, wrench = _wrenches(obj, 1)
            force.force, force.torque = wrench[0, :3].copy(), wrench[0, 3:].copy()
        for frame in self.frames:
            frame.read()
        for rest, spring in self.springs:  # a script may set a body's rest pose
            if "rest_position" in rest.dofs.attrs:  # (its position is the body's own)
                rest.read()
                spring.rest_position, spring.rest_rotation = rest.position, rest.rotation
        return state

    def write(self, state: State) -> None:
        for frame in self.frames:
            pose = np.concatenate([frame.position, Rotation.from_matrix(frame.rotation).as_quat()])
            array = pose[None].copy()
            array.flags.writeable = False
            frame.dofs.attrs["position"] = array


def rigid_model(
    builder: _Builder, dt: float, gravity: np.ndarray
) -> tuple[Model, list[SceneObject], RigidData]:
    """The model of a scene of rigid bodies alone, the MechanicalObjects of its bodies (in
    the model's order) and its hook (module docstring)."""
    root = builder.root
    friction = builder._friction()
    frames = {id(n): n for n in root.walk() if _spring_frame(builder, n)}
    nodes = [n for n in root.walk() if builder._is_rigid(n) and id(n) not in frames]
    bodies = [rigid_body(builder, n, friction) for n in nodes]
    by_node = {id(n): b for n, b in zip(nodes, bodies, strict=True)}
    held: list = []
    forces: list[tuple[SceneObject, WorldForce]] = []
    springs: list[tuple[_Frame, RestSpring]] = []
    for node, body in zip(nodes, bodies, strict=True):
        for obj in node.objects:
            if obj.type == SPRINGS:
                rest = _Frame(builder._rigid_dofs(node), np.zeros(3), np.eye(3))
                springs.append((rest, _spring(obj, body, rest)))
            elif obj.type in FIXED:
                held.append(AxisLock(body, [1] * 6, name=obj.path))
            elif obj.type == "ConstantForceField":
                force = WorldForce()
                body.forces.append(force)
                forces.append((obj, force))
    kinematic = [_Frame(builder._rigid_dofs(n), np.zeros(3), np.eye(3)) for n in frames.values()]
    for frame in kinematic:
        frame.read()
    contacts, obstacles = None, []
    if builder._detects():
        contacts, obstacles = _obstacles(builder, nodes, frames, kinematic, friction)
    joints = [*_joints(builder, by_node, frames), *held, *(s for _, s in springs)]
    try:
        model = Model(
            None,
            rigid_bodies=bodies,
            joints=joints,
            contacts=contacts,
            obstacles=obstacles,
            gravity=gravity,
            name=builder.path.stem,
        )
    except (ModelError, ContactError) as exc:
        raise SceneError(f"{builder.path.name}: {exc}") from exc
    dofs = [builder._one(n, {"MechanicalObject"}, "MechanicalObjects") for n in nodes]
    return model, dofs, RigidData(forces, kinematic, springs)


def _spring(obj: SceneObject, body: RigidBody, rest: _Frame) -> RestSpring:
    """A RestShapeSpringsForceField on a rigid body's frame: a RestSpring to its rest pose."""
    if obj.attrs.get("external_rest_shape") or np.size(field_numbers(obj, "points", [])) > 1:
        raise SceneError(
            f"{obj.path}: springs on a rigid body pull its one frame to its own rest pose"
            " (no external_rest_shape, one point)"
        )
    rest.read()
    k = field_numbers(obj, "stiffness", [1.0]).reshape(-1)
    k_turn = field_numbers(obj, "angularStiffness", [0.0]).reshape(-1)
    try:
        return RestSpring(
            body,
            k[0],
            k_turn[0] if k_turn.size else 0.0,
            rest.position,
            rest.rotation,
            name=obj.path,
        )
    except ModelError as exc:
        raise SceneError(f"{obj.path}: {exc}") from exc


def _obstacles(builder: _Builder, nodes, frames: dict, kinematic: list[_Frame], friction):
    """The still shapes (a Contacts) and the kinematic bodies of the spring-held frames."""
    inside = {id(c) for n in nodes for c in n.walk()}
    frame_of = {id(n): f for n, f in zip(frames.values(), kinematic, strict=True)}
    still, moving = [], []
    margin = 1.0
    intersection = [
        o for n in builder.root.walk() for o in n.objects if o.type in builder.intersections
    ]
    if intersection:
        margin = float(field_numbers(intersection[0], "alarmDistance", 1.0)[0])
    for node in builder.root.walk():
        types = {o.type for o in node.objects if o.type.endswith("CollisionModel")}
        if not types or id(node) in inside:
            continue
        parent = node.parent
        frame = frame_of.get(id(parent)) if parent is not None else None
        if frame is not None and any(o.type == "RigidMapping" for o in node.objects):
            if "TriangleCollisionModel" not in types:
                raise SceneError(f"{node.path}: a moving frame's obstacle collides by triangles")
            dofs = builder._one(node, {"MechanicalObject"}, "MechanicalObjects")
            try:
                points, faces = builder._positions(node, dofs), builder._faces(node)
                shape = TriangleMesh(points, faces, winding=True)
            except ContactError as exc:
                raise SceneError(f"{node.path}: {exc}") from exc
            moving.append(KinematicBody(shape, frame.pose, friction=friction, name=node.path))
            continue
        still.append(_bounded(builder, node, builder._obstacle(node)))
    if not still and not moving:
        return None, []
    shapes = [*still, *(o.shape for o in moving)]
    return Contacts(shapes, friction=friction, margin=margin), moving


def _bounded(builder: _Builder, node: SceneNode, shape):
    """A still flat mesh (read beside a deformable body as its infinite plane) as the slab
    under its triangles: a box as wide as they are and as deep as it is wide. Rigid bodies
    elsewhere do not touch it (SofaGym's CartPole: STLIB's floor is a 2 x 2 square far behind
    the cart)."""
    if not isinstance(shape, Plane):
        return shape
    dofs = builder._one(node, {"MechanicalObject"}, "MechanicalObjects")
    points = builder._positions(node, dofs)
    frame = builder._rigid_dofs(node.parent)
    if frame is not None and any(o.type == "RigidMapping" for o in node.objects):
        position, rotation = builder._pose(frame)
        points = points @ rotation.T + position
    normal = shape.rotation[:, 2]
    axes = np.column_stack([shape.rotation[:, 0], shape.rotation[:, 1], normal])
    local = (points - shape.position) @ axes
    lo, hi = local.min(axis=0), local.max(axis=0)
    half = 0.5 * (hi - lo)
    depth = max(half[0], half[1])
    if not depth > 0.0:
        raise SceneError(f"{node.path}: its triangles have no area")
    centre = 0.5 * (hi + lo)
    centre[2] = -depth
    return Box([half[0], half[1], depth], shape.position + axes @ centre, axes)


def _carrier(builder: _Builder, dofs: SceneObject, by_node: dict, frames: dict, where: str):
    """(rigid body or None, (k, 3) points in its frame, or in the world) of a joint's
    MechanicalObject."""
    node = dofs.node
    value = dofs.attrs.get("position")
    points = (
        np.asarray(data_value(value), dtype=float).reshape(-1, 3) if value is not None else None
    )
    if points is None or points.size == 0:
        points = builder._positions(node, dofs)
    if builder._rigid_dofs(node) is dofs:  # the frame itself: its origin
        if id(node) in by_node:
            return by_node[id(node)], np.zeros((1, 3))
        return None, builder._pose(dofs)[0][None]
    mapping = next((o for o in node.objects if o.type == "RigidMapping"), None)
    if mapping is None:
        if any(o.type.endswith("Mapping") for o in node.objects):
            raise SceneError(f"{where}: {dofs.path} is carried by a mapping Pliant does not follow")
        return None, points
    parent = _mapped_from(builder, node, mapping)
    if parent is not None and id(parent) in by_node:
        return by_node[id(parent)], points
    if parent is not None and id(parent) in frames:
        raise SceneError(
            f"{where}: a joint on a spring-held frame ({parent.path}) is not supported"
        )
    frame = builder._rigid_dofs(parent)
    if frame is None:
        raise SceneError(f"{where}: {dofs.path}'s RigidMapping has no Rigid3 frame to follow")
    position, rotation = builder._pose(frame)  # a still frame: world points
    return None, points @ rotation.T + position


def _mapped_from(builder: _Builder, node: SceneNode, mapping: SceneObject) -> SceneNode | None:
    """The node of a RigidMapping's input: its ``input`` link, else the nearest ancestor with
    a MechanicalObject (SOFA's context)."""
    link = mapping.attrs.get("input")
    if link is not None:
        dofs = builder.link_dofs(node, link)
        return None if dofs is None else dofs.node
    at = node.parent
    while at is not None and not any(o.type == "MechanicalObject" for o in at.objects):
        at = at.parent
    return at


def _index(obj: SceneObject, key: str, count: int) -> np.ndarray:
    idx = field_numbers(obj, key, [0]).astype(np.int64).reshape(-1)
    if idx.size == 0 or idx.min() < 0 or idx.max() >= count:
        raise SceneError(f"{obj.path}.{key}: indices in [0, {count}) expected, got {idx.tolist()}")
    return idx


def _joints(builder: _Builder, by_node: dict, frames: dict) -> list:
    joints = []
    for node in builder.root.walk():
        for obj in node.objects:
            if obj.type not in JOINTS:
                continue
            ends = []
            for key in ("object1", "object2"):
                link = obj.attrs.get(key)
                dofs = builder.link_dofs(node, link) if link is not None else None
                if dofs is None:
                    raise SceneError(f"{obj.path}.{key}: {link!r} names no MechanicalObject")
                ends.append(_carrier(builder, dofs, by_node, frames, obj.path))
            (body_a, points_a), (body_b, points_b) = ends
            if body_a is None:  # the moving one first
                (body_a, points_a), (body_b, points_b) = (body_b, points_b), (body_a, points_a)
            if body_a is None:
                raise SceneError(f"{obj.path}: it holds no moving rigid body")
            try:
                joints += _joint(obj, body_a, points_a, body_b, points_b, ends[0][0] is body_a)
            except ModelError as exc:
                raise SceneError(f"{obj.path}: {exc}") from exc
    return joints


def _joint(obj, body_a: RigidBody, points_a, body_b, points_b, in_order: bool) -> list:
    if obj.type == SLIDING:
        if not in_order:
            raise SceneError(f"{obj.path}: object1's sliding point must be on a moving body")
        point = points_a[_index(obj, "sliding_point", len(points_a))[0]]
        axis = [points_b[_index(obj, k, len(points_b))[0]] for k in ("axis_1", "axis_2")]
        return [SlidingJoint(body_a, point, *axis, body_b, name=obj.path)]
    template = str(obj.attrs.get("template", "Vec3"))
    if not template.startswith("Vec3"):
        raise SceneError(
            f"{obj.path}: a {template} BilateralInteractionConstraint between rigid bodies is"
            " not supported (Vec3 points only)"
        )
    first, second = ("first_point", "second_point") if in_order else ("second_point", "first_point")
    ia = _index(obj, first, len(points_a))
    ib = _index(obj, second, len(points_b))
    if ia.size != ib.size:
        raise SceneError(f"{obj.path}: first_point and second_point differ in length")
    return [
        BallJoint(body_a, points_a[i], body_b, points_b[j], name=f"{obj.path}[{k}]")
        for k, (i, j) in enumerate(zip(ia, ib, strict=True))
    ]
