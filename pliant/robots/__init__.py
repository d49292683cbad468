"""Robot builders with the reference parameters as defaults (SPEC §3).

``build("diamond", young_modulus=200)`` or the builders themselves, e.g.
:func:`pliant.robots.diamond`. Each registered robot also carries a scripted actuation for
``pliant run`` and a goal trajectory for ``pliant inverse``.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from pliant.errors import ModelError, UnknownRobotError
from pliant.model import Model
from pliant.robots import cartstem as _cartstem
from pliant.robots import catch_object as _catch_object
from pliant.robots import diamond as _diamond
from pliant.robots import finger as _finger
from pliant.robots import gripper as _gripper
from pliant.robots import multigait as _multigait
from pliant.robots import pneunet as _pneunet
from pliant.robots import rod_manipulator as _rod_manipulator
from pliant.robots import simple_maze as _simple_maze
from pliant.robots import tripod as _tripod
from pliant.robots import trunk as _trunk
from pliant.robots import trunk_cube as _trunk_cube
from pliant.robots import trunk_cup as _trunk_cup
from pliant.robots.diamond import diamond
from pliant.robots.finger import soft_finger
from pliant.robots.multigait import multigait
from pliant.robots.pneunet import pneunet
from pliant.robots.trunk import trunk


@dataclass(frozen=True)
class RobotEntry:
    """A registered robot: builder, scripted actuation (commands, or a control object such
    as trunk_push's inverse control with contacts, as a function of time), goal trajectories
    and camera."""

    build: Callable[..., Model]
    demo_actuation: Callable[[float], object]
    trajectories: dict[str, Callable[[int], np.ndarray]]
    view: tuple[float, float]


ROBOTS: dict[str, RobotEntry] = {
    "diamond": RobotEntry(
        diamond,
        _diamond.demo_actuation,
        {"circle": _diamond.circle, "lifted_circle": _diamond.lifted_circle},
        (20.0, -60.0),
    ),
    "trunk": RobotEntry(trunk, _trunk.demo_actuation, {"circle": _trunk.circle}, (20.0, -60.0)),
    "finger": RobotEntry(
        soft_finger, _finger.demo_actuation, {"closing": _finger.closing}, (10.0, -80.0)
    ),
    "pneunet": RobotEntry(
        pneunet, _pneunet.demo_actuation, {"bending": _pneunet.bending}, (10.0, -80.0)
    ),
    "multigait": RobotEntry(multigait, _multigait.demo_actuation, {}, (35.0, -60.0)),
    "cartstem_contact": RobotEntry(
        _cartstem.cartstem_contact, _cartstem.demo_actuation, {}, (5.0, -90.0)
    ),
    "cartstem_rod": RobotEntry(_cartstem.cartstem_rod, _cartstem.demo_actuation, {}, (5.0, -90.0)),
    "gripper": RobotEntry(_gripper.soft_gripper, _gripper.demo_actuation, {}, (15.0, -70.0)),
    "trunk_cube": RobotEntry(_trunk_cube.trunk_cube, _trunk_cube.demo_actuation, {}, (20.0, -60.0)),
    "trunk_push": RobotEntry(_trunk_cube.trunk_push, _trunk_cube.push_demo, {}, (20.0, -60.0)),
    "trunk_cup": RobotEntry(_trunk_cup.trunk_cup, _trunk_cup.demo_actuation, {}, (20.0, -60.0)),
    "catch_object": RobotEntry(
        _catch_object.catch_object, _catch_object.demo_actuation, {}, (10.0, -80.0)
    ),
    "rod_manipulator": RobotEntry(
        _rod_manipulator.rod_manipulator, _rod_manipulator.demo_actuation, {}, (45.0, -30.0)
    ),
    "tripod_maze": RobotEntry(_tripod.tripod_maze, _tripod.demo_actuation, {}, (35.0, -70.0)),
    "simple_maze": RobotEntry(
        _simple_maze.simple_maze, _simple_maze.demo_actuation, {}, (45.0, -70.0)
    ),
}


def entry(name: str) -> RobotEntry:
    try:
        return ROBOTS[name]
    except KeyError:
        raise UnknownRobotError(
            f"unknown robot {name!r}; available: {', '.join(sorted(ROBOTS))}"
        ) from None


def build(name: str, **kwargs) -> Model:
    """Build a registered robot by name with keyword overrides of its defaults; ModelError
    names a keyword the builder does not take and lists those it does."""
    builder = entry(name).build
    parameters = inspect.signature(builder).parameters
    if not any(p.kind is p.VAR_KEYWORD for p in parameters.values()):
        known = [
            k for k, p in parameters.items() if p.kind in (p.KEYWORD_ONLY, p.POSITIONAL_OR_KEYWORD)
        ]
        unknown = sorted(set(kwargs) - set(known))
        if unknown:
            raise ModelError(
                f"{name} has no builder keyword {', '.join(map(repr, unknown))}; its keywords:"
                f" {', '.join(known)}"
            )
    return builder(**kwargs)


__all__ = [
    "ROBOTS",
    "RobotEntry",
    "build",
    "diamond",
    "entry",
    "multigait",
    "pneunet",
    "soft_finger",
    "trunk",
]
