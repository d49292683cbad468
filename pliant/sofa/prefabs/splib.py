"""SPLIB3's helpers that scenes use, written for Pliant from SPLIB's documentation: the
animation manager and ``animate`` (callbacks driven by the simulated time), easing, numerics
(angles, 3-vectors, quaternions), key codes and point-list loading."""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from pliant.sofa.sofapython3 import Controller
from pliant.sofa.tree import SceneError, SceneNode


class Animation:
    """One clip: ``onUpdate(factor=f, **params)`` with f from 0 to 1 over `duration`
    seconds; then, by `mode`, "once" calls ``onDone``, "loop" starts again, "pingpong" runs
    back. SPLIB's keywords; the clock is the simulated time (``realTimeClock=True``, SPLIB's
    wall clock, would make a scene's result depend on the machine's speed)."""

    def __init__(
        self,
        onUpdate: Callable,  # noqa: N803 (SPLIB's keywords)
        params: dict,
        duration: float,
        mode: str = "once",
        onDone: Callable | None = None,  # noqa: N803
        realTimeClock: bool = False,  # noqa: N803
        terminationDelay: float | None = None,  # noqa: N803
    ):
        on_update, on_done = onUpdate, onDone
        self.on_update, self.params, self.duration = on_update, dict(params), float(duration)
        self.mode, self.on_done = mode, on_done
        self.start: float | None = self.params.pop("startTime", None)
        self.direction = 1.0
        self.factor = 0.0

    def update(self, time: float) -> bool:
        """Calls onUpdate at `time`; False once the clip is over."""
        if self.start is None:
            self.start = time
        progress = 1.0 if self.duration == 0.0 else (time - self.start) / self.duration
        # The clock sums time steps: a step that lands on the clip's end to round-off ends it.
        progress = 1.0 if progress > 1.0 - 1e-9 else max(progress, 0.0)
        self.factor = progress if self.direction > 0 else 1.0 - progress
        self.on_update(factor=self.factor, **self.params)
        if progress < 1.0:
            return True
        if self.mode in ("loop", "pingpong"):
            self.start = time
            if self.mode == "pingpong":
                self.direction = -self.direction
            return True
        if self.on_done is not None:
            self.on_done(factor=self.factor, **self.params)
        return False


class AnimationManagerController(Controller):
    """Advances the animations at each step's begin event, by the root's time step."""

    def __init__(self, node: SceneNode, *args, **kwargs):
        kwargs.setdefault("name", "AnimationManager")
        super().__init__(*args, **kwargs)
        self.node = node
        self.time = 0.0
        self.animations: list[Animation] = []
        if _ACTIVE.manager is None:  # made by the scene itself (SofaGym's): animate() uses it
            _ACTIVE.manager = self

    def addAnimation(self, animation: Animation) -> None:  # noqa: N802 (SPLIB's name)
        self.animations.append(animation)

    def onAnimateBeginEvent(self, event) -> None:  # noqa: N802
        self.time += float(self.node.getRoot().dt.value)
        self.animations = [a for a in self.animations if a.update(self.time)]


class Animations:
    """The scene's animation manager (one per loaded scene) and ``animate``."""

    def __init__(self) -> None:
        self.manager: AnimationManagerController | None = None

    def AnimationManager(self, node: SceneNode) -> AnimationManagerController:  # noqa: N802
        """The scene's manager, added to `node` the first time."""
        if self.manager is None:
            self.manager = AnimationManagerController(node)
            node.addObject(self.manager)
        return self.manager

    def animate(
        self,
        onUpdate: Callable,  # noqa: N803
        params: dict,
        duration: float,
        mode: str = "once",
        onDone: Callable | None = None,  # noqa: N803
        terminationDelay: float | None = None,  # noqa: N803
    ) -> Animation:
        """Starts a clip (see :class:`Animation`) on the scene's manager."""
        if self.manager is None:
            raise SceneError("animate() before an AnimationManager (MainHeader or Scene adds one)")
        animation = Animation(onUpdate, params, duration, mode, onDone)
        self.manager.addAnimation(animation)
        return animation


_ACTIVE = Animations()


def AnimationManager(node: SceneNode) -> AnimationManagerController:  # noqa: N802
    """The loaded scene's animation manager (added to `node` the first time)."""
    return _ACTIVE.AnimationManager(node)


def reset_animations() -> None:
    """A fresh manager for the next scene."""
    _ACTIVE.manager = None


def animate(onUpdate, params, duration, mode="once", onDone=None, terminationDelay=None):  # noqa: N803
    return _ACTIVE.animate(onUpdate, params, duration, mode, onDone, terminationDelay)


def LinearRamp(beginValue: float, endValue: float, scale: float) -> float:  # noqa: N802, N803
    """Linear interpolation from beginValue (scale 0) to endValue (scale 1)."""
    return (endValue - beginValue) * scale + beginValue


def to_radians(degrees):
    return np.radians(degrees) if np.ndim(degrees) else math.radians(degrees)


def to_degrees(radians):
    return np.degrees(radians) if np.ndim(radians) else math.degrees(radians)


def _euler(v, axes: str, degrees: bool = False) -> Rotation:
    """SPLIB's axes strings: "sxyz" static (extrinsic) axes, "rxyz" rotating (intrinsic)."""
    return Rotation.from_euler(axes[1:] if axes[0] == "s" else axes[1:].upper(), v, degrees)


class Vec3(np.ndarray):
    """SPLIB's 3-vector: a float array of three with in-place transforms."""

    def __new__(cls, *args):
        values = args[0] if len(args) == 1 else (args or (0.0, 0.0, 0.0))
        return np.array(values, dtype=float).reshape(3).view(cls)

    def getNorm(self) -> float:  # noqa: N802 (SPLIB's names)
        return float(np.linalg.norm(self))

    def toList(self) -> list:  # noqa: N802
        return [float(v) for v in self]

    def toString(self) -> str:  # noqa: N802
        return " ".join(str(v) for v in self.toList())

    def normalize(self, *args) -> Vec3:
        self[:] = self / (self.getNorm() if not args else args[0])
        return self

    def translate(self, *args) -> Vec3:
        self[:] = self + np.asarray(args[0] if len(args) == 1 else args, dtype=float)
        return self

    def scale(self, *args) -> Vec3:
        self[:] = self * np.asarray(args[0] if len(args) == 1 else args, dtype=float)
        return self

    def rotateFromQuat(self, q) -> Vec3:  # noqa: N802
        self[:] = Rotation.from_quat(np.asarray(q, dtype=float)).apply(np.asarray(self))
        return self

    def rotateFromEuler(self, v, axis: str = "sxyz") -> Vec3:  # noqa: N802
        self[:] = _euler(v, axis).apply(np.asarray(self))
        return self

    def rotateFromAxisAngle(self, axis, angle: float) -> Vec3:  # noqa: N802
        return self.rotateFromQuat(Quat.createFromAxisAngle(axis, angle))

    @staticmethod
    def dot(v1, v2) -> float:
        return float(np.dot(v1, v2))

    @staticmethod
    def cross(v1, v2) -> Vec3:
        return Vec3(np.cross(v1, v2))


def vadd(a, b) -> list:
    """a + b as a list, as SPLIB's (scenes concatenate it with a quaternion's list)."""
    return [float(v) for v in np.add(a, b)]


def vsub(a, b) -> list:
    """a - b as a list, as SPLIB's."""
    return [float(v) for v in np.subtract(a, b)]


class Quat(np.ndarray):
    """SPLIB's unit quaternion [x, y, z, w] (SOFA's order), composed with scipy."""

    def __new__(cls, *args):
        values = args[0] if len(args) == 1 else (args or (0.0, 0.0, 0.0, 1.0))
        return np.array(values, dtype=float).reshape(4).view(cls)

    @staticmethod
    def createFromEuler(v, axes: str = "sxyz", inDegree: bool = False) -> Quat:  # noqa: N802, N803
        return Quat(_euler(v, axes, inDegree).as_quat())

    @staticmethod
    def createFromAxisAngle(axis, angle: float) -> Quat:  # noqa: N802
        axis = np.asarray(axis, dtype=float)
        return Quat(Rotation.from_rotvec(axis / np.linalg.norm(axis) * angle).as_quat())

    @staticmethod
    def createFromVectors(v1, v2) -> Quat:  # noqa: N802
        rotation, _ = Rotation.align_vectors([np.asarray(v2, float)], [np.asarray(v1, float)])
        return Quat(rotation.as_quat())

    @staticmethod
    def product(qa, qb) -> Quat:
        return Quat((Rotation.from_quat(qa) * Rotation.from_quat(qb)).as_quat())

    def _rotation(self) -> Rotation:
        return Rotation.from_quat(np.asarray(self))

    def normalize(self, *_args) -> None:
        self[:] = self / np.linalg.norm(self)

    def rotateFromQuat(self, qb) -> None:  # noqa: N802
        self[:] = (self._rotation() * Rotation.from_quat(qb)).as_quat()

    def rotateFromEuler(self, v, axes: str = "sxyz") -> None:  # noqa: N802
        self.rotateFromQuat(Quat.createFromEuler(v, axes))

    def rotate(self, v):
        return self._rotation().apply(np.asarray(v, dtype=float))

    def getNorm(self) -> float:  # noqa: N802
        return float(np.linalg.norm(self))

    def getAxisAngle(self):  # noqa: N802
        rotvec = self._rotation().as_rotvec()
        angle = float(np.linalg.norm(rotvec))
        return (rotvec / angle if angle else np.array([1.0, 0.0, 0.0])), angle

    def getEulerAngles(self, axes: str = "sxyz"):  # noqa: N802
        frame = axes[1:] if axes[0] == "s" else axes[1:].upper()
        return self._rotation().as_euler(frame)

    def getMatrix(self):  # noqa: N802
        return self._rotation().as_matrix()

    def getConjugate(self) -> Quat:  # noqa: N802
        return Quat([-self[0], -self[1], -self[2], self[3]])

    getInverse = getConjugate  # noqa: N815 (a unit quaternion)

    def toList(self) -> list:  # noqa: N802
        return [float(v) for v in self]


def getOrientedBoxFromTransform(  # noqa: N802
    translation=(0.0, 0.0, 0.0),
    rotation=(0.0, 0.0, 0.0, 1.0),
    eulerRotation=None,  # noqa: N803
    scale=(1.0, 1.0, 1.0),
) -> list[float]:
    """SOFA's ``orientedBox`` (three corners of a face and the depth) of a unit cube
    centred at the origin, scaled, rotated (a quaternion, or Euler angles in degrees) and
    translated."""
    turn = (
        Rotation.from_euler("xyz", eulerRotation, degrees=True)
        if eulerRotation is not None
        else Rotation.from_quat(rotation)
    )
    half = 0.5 * np.asarray(scale, dtype=float)
    corners = np.array([[-1.0, -1.0, 0.0], [1.0, -1.0, 0.0], [1.0, 1.0, 0.0]]) * half
    corners = turn.apply(corners) + np.asarray(translation, dtype=float)
    return [*corners.ravel().tolist(), float(2.0 * half[2])]


class RigidDof:
    """SPLIB's handle on a Rigid3 MechanicalObject's first frame, in the world as SOFA holds
    it after ``init`` (the object's ``translation`` and ``rotation`` applied): ``position``,
    ``rest_position``, ``orientation``, ``forward`` (its z axis), ``left`` (x), ``up`` (y)
    read; ``setPosition`` (and ``position = ...``) moves the origin of a servo's base, once the
    scene steps (the servo slides with it). Anything else is named in the scene's error."""

    def __init__(self, rigidobject) -> None:
        self.__dict__["rigidobject"] = rigidobject

    def _transform(self) -> tuple[Rotation, np.ndarray]:
        attrs = self.rigidobject.attrs
        turn = Rotation.from_euler("xyz", _vector(attrs.get("rotation", [0, 0, 0])), True)
        return turn, _vector(attrs.get("translation", [0, 0, 0]))

    def _frame(self, field: str) -> np.ndarray:
        attrs = self.rigidobject.attrs
        value = attrs.get(field, attrs.get("position", [0, 0, 0, 0, 0, 0, 1]))
        frame = _vector(value)
        if frame.size < 7:
            raise SceneError(f"{self.rigidobject.path}.{field}: no Rigid3 frame")
        return frame[:7]

    def getPosition(self, index: int = 0, field: str = "position") -> np.ndarray:  # noqa: N802
        if index != 0:
            raise SceneError(f"{self.rigidobject.path}: RigidDof reads frame 0 only")
        turn, shift = self._transform()
        return turn.apply(self._frame(field)[:3]) + shift

    def setPosition(self, v, field: str = "position") -> None:  # noqa: N802
        if not self.rigidobject.__dict__.get("servo_base", False):
            raise SceneError(
                f"splib3.numerics.RigidDof.setPosition (on {self.rigidobject.getPathName()}):"
                " Pliant moves a servo's base only (read as the scene steps), not another frame"
            )
        turn, shift = self._transform()
        frame = self._frame(field)
        local = turn.inv().apply(np.asarray(v, dtype=float).reshape(3) - shift)
        self.rigidobject.attrs[field] = [[*local.tolist(), *frame[3:].tolist()]]

    def getOrientation(self, field: str = "position") -> np.ndarray:  # noqa: N802
        turn, _ = self._transform()
        return (turn * Rotation.from_quat(self._frame(field)[3:])).as_quat()

    def _axis(self, axis) -> np.ndarray:
        return Rotation.from_quat(self.getOrientation()).apply(axis)

    forward = property(lambda self: self._axis([0.0, 0.0, 1.0]))
    left = property(lambda self: self._axis([1.0, 0.0, 0.0]))
    up = property(lambda self: self._axis([0.0, 1.0, 0.0]))

    def __getattr__(self, key: str):
        if key.startswith("__"):
            raise AttributeError(key)
        if key in ("position", "rest_position"):
            return self.getPosition(field=key)
        if key in ("orientation", "rest_orientation"):
            return self.getOrientation(field=key.replace("orientation", "position"))
        raise SceneError(
            f"splib3.numerics.RigidDof.{key} (on {self.rigidobject.getPathName()}): Pliant"
            " reads a frame's position and orientation and moves its origin only"
        )

    def __setattr__(self, key: str, value) -> None:
        if key in ("position", "rest_position"):
            self.setPosition(value, field=key)
            return
        raise SceneError(
            f"splib3.numerics.RigidDof.{key} (on {self.rigidobject.getPathName()}): Pliant"
            " moves a frame's origin only (setPosition)"
        )


def _vector(value) -> np.ndarray:
    if isinstance(value, str):
        value = value.replace(",", " ").split()
    return np.asarray(value, dtype=float).reshape(-1)


def setData(target, **values) -> None:  # noqa: N802
    """Sets several data fields of a component or node."""
    for key, value in values.items():
        setattr(target, key, value)


class SofaPrefab:
    """SPLIB's prefab decorator, also a base class: as a decorator the class is returned
    unchanged (Pliant's tree needs no registration); a subclass is a plain Python class."""

    def __new__(cls, *args, **kwargs):
        if cls is SofaPrefab and len(args) == 1 and isinstance(args[0], type) and not kwargs:
            return args[0]
        return super().__new__(cls)


class SofaObject:
    """SPLIB's base of prefabs written as Python classes: a node (``self.node``, a child
    `name` of `node`) whose children, components and data the object answers as its own."""

    def __init__(self, node: SceneNode, name: str) -> None:
        self.node = node.addChild(name)

    def __getattr__(self, key: str):
        if key.startswith("__") or "node" not in self.__dict__:
            raise AttributeError(key)
        return getattr(self.node, key)


def getLoadingLocation(filename: str, source: str) -> str:  # noqa: N802
    """`filename` in the folder of the file `source` (a scene's ``__file__``)."""
    return str(Path(source).resolve().parent / filename)


def loadPointListFromFile(path: str | Path):  # noqa: N802
    """A JSON list of points."""
    return json.loads(Path(path).read_text())
