"""SoftRobots' servo motors as SOFA's ArticulatedSystemPlugin builds them, read as Pliant's
kinematic servos (:func:`pliant.fem.rigid.servo`).

The S90 servo of SoftRobots' tutorials is a ``Vec1`` MechanicalObject (the articulation's
angle) under an ``ArticulatedHierarchyContainer``, pulled to its ``rest_position`` (the
servo's ``angleIn``) by a ``RestShapeSpringsForceField``, and a child whose ``Rigid3`` frames
an ``ArticulatedSystemMapping`` computes from the angle and from a base frame (the servo's
body, held by a ``FixedProjectiveConstraint``): frame 0 is the base, frame 1 the wheel, turned
by the angle about the ``Articulation``'s ``rotationAxis`` (in the base's frame) through the
``ArticulationCenter``'s ``posOnParent``. SOFA's spring (stiffness 1e9 N mm / rad in the
tutorial) brings the angle to its command within a step; Pliant takes the angle as the
command itself, reached at the end of the step in which a controller sets it: a
:class:`pliant.fem.rigid.KinematicBody` on a servo trajectory, which carries the body's nodes
that Rigidify's frames map from the wheel (:class:`pliant.fem.rigid.DrivenNodes`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation

from pliant.fem.rigid import KinematicBody, servo
from pliant.geometry.collision import Box
from pliant.sofa.tree import SceneError, SceneNode, SceneObject

# The components of an articulated system Pliant reads as a servo.
ARTICULATED = frozenset(
    {
        "ArticulatedHierarchyContainer",
        "ArticulatedSystemMapping",
        "ArticulationCenter",
        "Articulation",
    }
)


def _numbers(value, what: str) -> np.ndarray:
    if isinstance(value, str):
        value = value.replace(",", " ").split()
    try:
        return np.asarray(value, dtype=float).reshape(-1)
    except (TypeError, ValueError) as exc:
        raise SceneError(f"{what}: numbers expected, got {value!r}") from exc


def _flag(value) -> bool:
    if isinstance(value, str):
        return value.strip().lower() not in ("0", "false", "")
    return bool(value)


def data_value(obj: SceneObject | SceneNode, key: str, default=None, depth: int = 0):
    """A data field's value, following ``@path.field`` links: by the path where it leads to a
    node or component holding the field, else (a link made while a prefab was not yet in the
    scene, "@/.angleIn") the nearest ancestor holding it."""
    value = obj.attrs.get(key, default)
    if not (isinstance(value, str) and value.strip().startswith("@")) or depth > 16:
        return value
    target, _, name = value.strip()[1:].rpartition(".")
    node = obj.node if isinstance(obj, SceneObject) else obj
    root = node.getRoot()
    for candidate in root.walk():
        for holder in [candidate, *candidate.objects]:
            path = holder.getPathName() if isinstance(holder, SceneObject) else holder.sofa_path
            if path == (target or "/") and holder is not obj and name in holder.attrs:
                return data_value(holder, name, default, depth + 1)
    at = node if isinstance(obj, SceneObject) else node.parent
    while at is not None:
        if name in at.attrs and at is not obj:
            return data_value(at, name, default, depth + 1)
        at = at.parent
    raise SceneError(f"{obj.path}.{key}: the link {value!r} names no data field")


def rigid_pose(dofs: SceneObject, index: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """A Rigid3 MechanicalObject's frame `index`: its ``position`` (x y z, quaternion x y z
    w) under the object's ``rotation`` (Euler angles, degrees) and ``translation``."""
    pose = _numbers(dofs.attrs.get("position", [0, 0, 0, 0, 0, 0, 1]), f"{dofs.path}.position")
    if pose.size % 7 or pose.size // 7 <= index:
        raise SceneError(f"{dofs.path}.position: no Rigid3 frame {index}")
    pose = pose.reshape(-1, 7)[index]
    euler = _numbers(dofs.attrs.get("rotation", [0, 0, 0]), f"{dofs.path}.rotation")
    shift = _numbers(dofs.attrs.get("translation", [0, 0, 0]), f"{dofs.path}.translation")
    turn = Rotation.from_euler("xyz", euler, degrees=True)
    return turn.apply(pose[:3]) + shift, (turn * Rotation.from_quat(pose[3:])).as_matrix()


@dataclass
class Servo:
    """One articulated servo: the angle's MechanicalObject, its commanded angle over time,
    and the kinematic wheel it turns."""

    angle_dofs: SceneObject
    spring: SceneObject
    wheel: SceneNode
    carrier: KinematicBody
    # (time the command was set, angle), in time order: the wheel reaches each command at
    # the end of the step that begins at its time.
    commands: list[tuple[float, float]] = field(default_factory=list)
    # The base's MechanicalObject, and (time, shift of its origin) in time order: a script
    # slides the base (SPLIB's RigidDof.setPosition), reached as a command is.
    base: SceneObject | None = None
    slides: list[tuple[float, np.ndarray]] = field(default_factory=list)

    def angle(self, t: float) -> float:
        current = self.commands[0][1]
        for since, value in self.commands:
            if since < t:
                current = value
        return current

    def shift(self, t: float) -> np.ndarray:
        current = np.zeros(3)
        for since, value in self.slides:
            if since < t:
                current = value
        return current

    def command(self) -> float:
        """The angle the scene's data command now (the spring's rest angle)."""
        rest = data_value(self.angle_dofs, "rest_position", None)
        if rest is None:
            rest = self.angle_dofs.attrs.get("position", 0.0)
        values = _numbers(rest, f"{self.angle_dofs.path}.rest_position")
        if values.size != 1 or not math.isfinite(values[0]):
            raise SceneError(f"{self.angle_dofs.path}.rest_position: one finite angle expected")
        return float(values[0])

    def set_command(self, t: float) -> None:
        value = self.command()
        if value != self.commands[-1][1]:
            self.commands = [c for c in self.commands if c[0] < t] + [(t, value)]
            self.carrier.forget()
        if self.base is None:
            return
        position, rotation = rigid_pose(self.base)
        if np.abs(rotation - self._base_pose[1]).max() > 1e-9:
            raise SceneError(
                f"{self.base.path}: a script turned a servo's base; Pliant slides it only"
            )
        shift = position - self._base_pose[0]
        if not np.array_equal(shift, self.shift(math.inf)):
            self.slides = [c for c in self.slides if c[0] < t] + [(t, shift)]
            self.carrier.forget()

    def write(self, t: float) -> None:
        """The angle and the wheel's frames into the scene's data."""
        self.angle_dofs.attrs["position"] = [[self.angle(t)]]
        dofs = self.wheel.getMechanicalState()
        base = self._base_pose
        x, r = self.carrier.pose(t)
        poses = [
            np.concatenate([base[0] + self.shift(t), Rotation.from_matrix(base[1]).as_quat()]),
            np.concatenate([x, Rotation.from_matrix(r).as_quat()]),
        ]
        dofs.attrs["position"] = np.array(poses)

    _base_pose: tuple = ()


def read_servos(root: SceneNode) -> dict[int, Servo]:
    """Every servo of the scene, by the id of its wheel's node (see the module text); an
    articulated system of another form is refused with what differs."""
    servos: dict[int, Servo] = {}
    for node in root.walk():
        if not any(o.type == "ArticulatedHierarchyContainer" for o in node.objects):
            continue
        where = f"{node.path} (an articulated system)"
        angle_dofs = node.getMechanicalState()
        if angle_dofs is None or str(angle_dofs.attrs.get("template", "")) != "Vec1":
            raise SceneError(f"{where}: its angles are a Vec1 MechanicalObject in Pliant")
        springs = [o for o in node.objects if o.type == "RestShapeSpringsForceField"]
        if len(springs) != 1:
            raise SceneError(
                f"{where}: Pliant reads a servo, its angle held by one RestShapeSpringsForceField"
                " to its rest_position (the servo's command)"
            )
        centres = [o for n in node.walk() for o in n.objects if o.type == "ArticulationCenter"]
        joints = [o for n in node.walk() for o in n.objects if o.type == "Articulation"]
        wheels = [
            (n, o) for n in node.children for o in n.objects if o.type == "ArticulatedSystemMapping"
        ]
        if len(centres) != 1 or len(joints) != 1 or len(wheels) != 1:
            raise SceneError(
                f"{where}: Pliant reads one ArticulationCenter with one Articulation and one"
                f" ArticulatedSystemMapping (got {len(centres)}, {len(joints)}, {len(wheels)})"
            )
        centre, joint, (wheel, mapping) = centres[0], joints[0], wheels[0]
        if (
            _flag(joint.attrs.get("translation", False))
            or not _flag(joint.attrs.get("rotation", True))
            or int(float(joint.attrs.get("articulationIndex", 0))) != 0
        ):
            raise SceneError(f"{joint.path}: Pliant reads a rotation of articulation 0 only")
        parent = int(float(centre.attrs.get("parentIndex", 0)))
        child = int(float(centre.attrs.get("childIndex", 1)))
        if (parent, child) != (0, 1):
            raise SceneError(f"{centre.path}: Pliant reads parentIndex 0, childIndex 1")
        on_child = _numbers(centre.attrs.get("posOnChild", [0, 0, 0]), f"{centre.path}.posOnChild")
        on_parent = _numbers(
            centre.attrs.get("posOnParent", [0, 0, 0]), f"{centre.path}.posOnParent"
        )
        base_link = str(mapping.attrs.get("input2", "")).strip().lstrip("@")
        base = linked_dofs(wheel, base_link)
        if base is None:
            raise SceneError(f"{mapping.path}.input2: {base_link!r} names no Rigid3 base")
        held = any(
            o.type in ("FixedConstraint", "FixedProjectiveConstraint") for o in base.node.objects
        )
        if not held:
            raise SceneError(
                f"{base.path}: a servo's base is held by a FixedProjectiveConstraint in Pliant"
            )
        position, rotation = rigid_pose(base)
        axis = rotation @ _numbers(joint.attrs.get("rotationAxis", [1, 0, 0]), "rotationAxis")
        pivot = position + rotation @ on_parent
        # the wheel at angle 0: the base, its origin moved so that posOnChild is on the pivot
        wheel_origin = pivot - rotation @ on_child
        made = Servo(angle_dofs, springs[0], wheel, None)  # type: ignore[arg-type]
        given = angle_dofs.attrs.get("position", [0.0])
        try:
            start = float(_numbers(given, f"{angle_dofs.path}.position")[0])
        except (SceneError, TypeError, ValueError):  # a data field set there: its command's
            made.commands = [(-math.inf, 0.0)]
            start = made.command()
        made.commands = [(-math.inf, start)]
        turned = servo(pivot, axis, made.angle, wheel_origin, rotation)
        made.carrier = KinematicBody(
            Box(np.full(3, 1e-3), position=wheel_origin, rotation=rotation),
            _slid(turned, made.shift),
            name=str(node.parent.name if node.parent is not None else node.name),
        )
        made._base_pose = (position, rotation)
        made.base = base
        object.__setattr__(base, "servo_base", True)  # a script's RigidDof may slide it
        # SOFA's rest_position: the position the scene gave (a script's RigidDof reads it)
        base.attrs.setdefault("rest_position", base.attrs.get("position", [0, 0, 0, 0, 0, 0, 1]))
        servos[id(wheel)] = made
    return servos


def _slid(turned, shift):
    """The wheel's trajectory: turned by the servo, shifted with its base."""

    def pose(t: float) -> tuple[np.ndarray, np.ndarray]:
        x, r = turned(t)
        return x + shift(t), r

    return pose


def linked_dofs(node: SceneNode, link: str) -> SceneObject | None:
    """The MechanicalObject a mapping's input link names from `node`: a node's (its state),
    or a MechanicalObject by its path."""
    path = str(link).strip().lstrip("@")
    at: SceneNode | None = node.getRoot() if path.startswith("/") else node
    for part in [p for p in path.split("/") if p not in ("", ".")]:
        if at is None:
            return None
        if part == "..":
            at = at.parent
            continue
        child = next((c for c in at.children if c.name == part), None)
        if child is None:
            found = next((o for o in at.objects if o.name == part), None)
            return found if found is not None and found.type == "MechanicalObject" else None
        at = child
    return None if at is None else at.getMechanicalState()
