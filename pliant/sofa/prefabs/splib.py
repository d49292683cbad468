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
    back."""

    def __init__(self, on_update: Callable, params: dict, duration: float, mode: str, on_done):
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
        progress = min(max(progress, 0.0), 1.0)
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
        super().__init__(*args, name="AnimationManager", **kwargs)
        self.node = node
        self.time = 0.0
        self.animations: list[Animation] = []

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


class Vec3(list):
    """A 3-vector as a list, with the norm and arithmetic scenes use."""

    def __init__(self, *values):
        super().__init__(values[0] if len(values) == 1 else (values or (0.0, 0.0, 0.0)))

    def norm(self) -> float:
        return float(np.linalg.norm(self))

    def __add__(self, other):
        return Vec3(list(np.add(self, other)))

    def __sub__(self, other):
        return Vec3(list(np.subtract(self, other)))

    def __mul__(self, scale):
        return Vec3(list(np.multiply(self, scale)))


class Quat(list):
    """A unit quaternion [x, y, z, w] (SOFA's order), built and composed with scipy."""

    def __init__(self, *values):
        super().__init__(values[0] if len(values) == 1 else (values or (0.0, 0.0, 0.0, 1.0)))

    @staticmethod
    def createFromEuler(angles, axes: str = "sxyz", inDegree: bool = False) -> Quat:  # noqa: N802, N803
        frame = axes[1:] if axes[0] == "s" else axes[1:].upper()
        return Quat(list(Rotation.from_euler(frame, angles, degrees=inDegree).as_quat()))

    @staticmethod
    def createFromAxisAngle(axis, angle: float) -> Quat:  # noqa: N802
        axis = np.asarray(axis, dtype=float)
        return Quat(list(Rotation.from_rotvec(axis / np.linalg.norm(axis) * angle).as_quat()))

    def rotateFromQuat(self, other) -> None:  # noqa: N802
        self[:] = (Rotation.from_quat(other) * Rotation.from_quat(self)).as_quat().tolist()

    def rotateFromEuler(self, angles, axes: str = "sxyz", inDegree: bool = False) -> None:  # noqa: N802, N803
        self.rotateFromQuat(Quat.createFromEuler(angles, axes, inDegree))

    def getEulerAngles(self, axes: str = "sxyz"):  # noqa: N802
        frame = axes[1:] if axes[0] == "s" else axes[1:].upper()
        return Rotation.from_quat(self).as_euler(frame).tolist()

    def getMatrix(self):  # noqa: N802
        return Rotation.from_quat(self).as_matrix()


def loadPointListFromFile(path: str | Path):  # noqa: N802
    """A JSON list of points."""
    return json.loads(Path(path).read_text())
