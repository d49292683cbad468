"""Robot builders with the reference parameters as defaults (SPEC §3).

``build("diamond", young_modulus=200)`` or the builders themselves, e.g.
:func:`pliant.robots.diamond`. Each registered robot also carries a scripted actuation for
``pliant run`` and a goal trajectory for ``pliant inverse``.
"""

from __future__ import annotations

import collections.abc
import inspect
import numbers
import types
import typing
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from pliant.errors import ModelError, PliantError, UnknownRobotError
from pliant.model import Model
from pliant.robots import bubble_motion as _bubble_motion
from pliant.robots import cartstem as _cartstem
from pliant.robots import catch_object as _catch_object
from pliant.robots import diamond as _diamond
from pliant.robots import finger as _finger
from pliant.robots import gripper as _gripper
from pliant.robots import lianford as _lianford
from pliant.robots import multigait as _multigait
from pliant.robots import pneunet as _pneunet
from pliant.robots import rod_manipulator as _rod_manipulator
from pliant.robots import simple_maze as _simple_maze
from pliant.robots import stem_pendulum as _stem_pendulum
from pliant.robots import stiff_flop as _stiff_flop
from pliant.robots import tripod as _tripod
from pliant.robots import trunk as _trunk
from pliant.robots import trunk_cube as _trunk_cube
from pliant.robots import trunk_cup as _trunk_cup
from pliant.robots import trunk_debris as _trunk_debris
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
    "cartstem": RobotEntry(_cartstem.cartstem, _cartstem.demo_actuation, {}, (5.0, -90.0)),
    "bubble_motion": RobotEntry(
        _bubble_motion.bubble_motion, _bubble_motion.demo_actuation, {}, (35.0, -60.0)
    ),
    "stem_pendulum": RobotEntry(
        _stem_pendulum.stem_pendulum, _stem_pendulum.demo_actuation, {}, (5.0, -90.0)
    ),
    "cartstem_rod": RobotEntry(_cartstem.cartstem_rod, _cartstem.demo_actuation, {}, (5.0, -90.0)),
    "gripper": RobotEntry(_gripper.soft_gripper, _gripper.demo_actuation, {}, (15.0, -70.0)),
    "trunk_cube": RobotEntry(_trunk_cube.trunk_cube, _trunk_cube.demo_actuation, {}, (20.0, -60.0)),
    "trunk_push": RobotEntry(_trunk_cube.trunk_push, _trunk_cube.push_demo, {}, (20.0, -60.0)),
    "trunk_cup": RobotEntry(_trunk_cup.trunk_cup, _trunk_cup.demo_actuation, {}, (20.0, -60.0)),
    "trunk_space_debris": RobotEntry(
        _trunk_debris.trunk_space_debris, _trunk_debris.demo_actuation, {}, (20.0, -90.0)
    ),
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
    "lianford": RobotEntry(
        _lianford.lianford, _lianford.demo_actuation, {"spiral": _lianford.spiral}, (30.0, -60.0)
    ),
    "stiff_flop": RobotEntry(
        _stiff_flop.stiff_flop,
        _stiff_flop.demo_actuation,
        {"circle": _stiff_flop.circle, "spiral": _stiff_flop.spiral},
        (20.0, -60.0),
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
    """Build a registered robot by name with keyword overrides of its defaults.

    Each keyword is checked against the builder's signature and type hints (a float is a
    real number, a Literal one of its values, a tuple of the right length, ...)
    before anything is meshed, and ModelError names the keyword. A builder that still fails
    on its keywords (a size that leaves no geometry) raises ModelError naming them too.
    """
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
    try:
        hints = typing.get_type_hints(builder)
    except Exception:  # hints that do not resolve: the builder checks its keywords itself
        hints = {}
    for key, value in kwargs.items():
        if key in hints and not _fits(value, hints[key]):
            raise ModelError(f"{name}: {key} must be {_describe(hints[key])}, got {value!r}")
    if not kwargs:
        return builder()
    try:
        return builder(**kwargs)
    except PliantError:
        raise
    except Exception as exc:  # e.g. gmsh failing on a size that leaves no geometry
        raise ModelError(
            f"{name} cannot be built with {kwargs}: {type(exc).__name__}: {exc}"
        ) from exc


def _fits(value, hint) -> bool:
    """Whether `value` is of the type `hint` (float: a real number; int: an
    integer; a Literal: one of its values; X | None; tuple[...]; classes); hints of other
    forms are not checked here."""
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if hint is float:  # its range (NaN included) is the builder's to check
        return _real(value)
    if hint is int:
        return isinstance(value, numbers.Integral) and not isinstance(value, (bool, np.bool_))
    if hint is bool:
        return isinstance(value, (bool, np.bool_))
    if hint is str:
        return isinstance(value, str)
    if origin is typing.Literal:
        return any(value == a and type(value) is type(a) for a in args)
    if origin in (types.UnionType, typing.Union):
        return any(_fits(value, a) for a in args)
    if hint is type(None):
        return value is None
    if origin is tuple:
        if isinstance(value, (str, bytes)) or not isinstance(value, Sequence | np.ndarray):
            return False
        if len(args) == 2 and args[1] is Ellipsis:
            return all(_fits(v, args[0]) for v in value)
        return len(value) == len(args) and all(
            _fits(v, a) for v, a in zip(value, args, strict=True)
        )
    if origin is collections.abc.Callable or hint is collections.abc.Callable:
        return callable(value)
    if isinstance(hint, type):
        return isinstance(value, hint)
    return True


def _real(value) -> bool:
    return isinstance(value, numbers.Real) and not isinstance(value, (bool, np.bool_))


def _describe(hint) -> str:
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if hint is float:
        return "a real number"
    if hint is int:
        return "an integer"
    if origin is typing.Literal:
        return "one of " + ", ".join(map(repr, args))
    if origin in (types.UnionType, typing.Union):
        return " or ".join(_describe(a) for a in args)
    if hint is type(None):
        return "None"
    if origin is tuple:
        return f"a sequence of {len(args)} values ({', '.join(_describe(a) for a in args)})"
    return getattr(hint, "__name__", str(hint))


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
