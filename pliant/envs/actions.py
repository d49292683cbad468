"""Action maps: how an environment's action becomes the commands of a step.

An action map turns its part of an action into :class:`Commands`, the step's targets: the
actuators' commands at the step's end (reached linearly over the sub-steps), the kinematic
inputs' (:class:`pliant.envs.base.Ramp`) targets at the step's end, and what the map
remembers between steps (a cart's commanded target, kept in the task so that snapshots carry
it). A map reads the environment (its commands, ramps, time and task) and writes nothing:
:meth:`pliant.envs.base.SoftRobotEnv.step` applies what it returns.

Maps compose with ``+``: each map of a sum owns a block of the discrete actions and a slice of
the continuous action, in order, and every map is asked at every step (a discrete action of
another map's block reaches it as ``None``: what it holds, a cart still moving towards its
target, goes on). The maps here are the ones several environments share:

- :class:`ActuatorTargets`: commands in [0, max] (cables' displacements, cavities' pressures),
  discrete increments or continuous targets or increments;
- :class:`RampTarget`: a kinematic input (a cart, a carriage, a base, a maze's tilt, servos)
  moved towards a target in [low, high], at a bounded speed where one is given.

An environment's own maps (Multigait's chamber groups, the pendulum's torque, the
CatchTheObject gripper that closes by itself) subclass :class:`ActionMap` beside it.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any, Literal

import gymnasium as gym
import numpy as np

from pliant.envs.config import check_positive

if TYPE_CHECKING:
    from pliant.envs.base import SoftRobotEnv


@dataclass(frozen=True)
class Commands:
    """What one environment step asks of the simulation (see the module docstring)."""

    #: the actuators' commands at the step's end
    actuators: np.ndarray
    #: ramp name -> its target at the step's end (reached over the step)
    ramps: dict[str, np.ndarray] = field(default_factory=dict)
    #: task entries the maps remember (merged into the environment's task)
    task: dict[str, Any] = field(default_factory=dict)

    def with_actuators(self, targets: np.ndarray) -> Commands:
        return replace(self, actuators=targets)

    def with_ramp(self, name: str, target, /, **task) -> Commands:
        return replace(self, ramps={**self.ramps, name: target}, task={**self.task, **task})

    def with_task(self, **task) -> Commands:
        return replace(self, task={**self.task, **task})


def scaled_box(low, high, shape) -> gym.spaces.Box:
    """A float32 box of `shape` between `low` and `high` (broadcast)."""
    return gym.spaces.Box(
        np.broadcast_to(np.asarray(low, np.float32), shape).copy(),
        np.broadcast_to(np.asarray(high, np.float32), shape).copy(),
        dtype=np.float32,
    )


def discrete_increments(n: int, scale) -> np.ndarray:
    """(2n, n): action 2i adds `scale` (its i-th value, if an array) to command i, action 2i + 1
    removes it."""
    scale = np.broadcast_to(np.asarray(scale, dtype=float), (n,))
    table = np.zeros((2 * n, n))
    for i in range(n):
        table[2 * i, i] = scale[i]
        table[2 * i + 1, i] = -scale[i]
    return table


def in_interval(a, low, high):
    """An action in [-1, 1] mapped linearly onto [low, high]."""
    return low + 0.5 * (a + 1.0) * (high - low)


class ActionMap:
    """Part of an environment's action: `n_discrete` discrete actions and `n_continuous` values
    of the continuous action (in [-1, 1]). Subclasses implement :meth:`discrete` and
    :meth:`continuous`; each returns `commands` with its own targets set."""

    n_discrete: int = 0
    n_continuous: int = 0

    def discrete(self, env: SoftRobotEnv, action: int | None, commands: Commands) -> Commands:
        """`action` in [0, n_discrete), or None where another map's action was chosen."""
        raise NotImplementedError

    def continuous(self, env: SoftRobotEnv, action: np.ndarray, commands: Commands) -> Commands:
        raise NotImplementedError

    def __call__(self, env: SoftRobotEnv, action) -> Commands:
        """The step's commands for a valid action of ``env.action_space``."""
        start = Commands(env.commands.copy())
        if env.action_type == "discrete":
            return self.discrete(env, action, start)
        return self.continuous(env, action, start)

    def space(self, action_type: str) -> gym.Space:
        if action_type == "discrete":
            return gym.spaces.Discrete(self.n_discrete)
        return scaled_box(-1.0, 1.0, (self.n_continuous,))

    def __add__(self, other: ActionMap) -> ActionMaps:
        return ActionMaps(self, other)


class ActionMaps(ActionMap):
    """Maps side by side (``a + b``): the discrete actions of each in turn, the continuous
    action their values concatenated."""

    def __init__(self, *maps: ActionMap) -> None:
        self.maps: list[ActionMap] = []
        for m in maps:
            self.maps.extend(m.maps if isinstance(m, ActionMaps) else [m])
        self.n_discrete = sum(m.n_discrete for m in self.maps)
        self.n_continuous = sum(m.n_continuous for m in self.maps)

    def discrete(self, env, action, commands):
        offset = 0
        for m in self.maps:
            mine = action is not None and offset <= action < offset + m.n_discrete
            commands = m.discrete(env, action - offset if mine else None, commands)
            offset += m.n_discrete
        return commands

    def continuous(self, env, action, commands):
        offset = 0
        for m in self.maps:
            commands = m.continuous(env, action[offset : offset + m.n_continuous], commands)
            offset += m.n_continuous
        return commands


class ActuatorTargets(ActionMap):
    """Commands in [0, high] of the actuators `driven` (all by default): cables' displacements,
    cavities' pressures.

    Discrete: action 2k raises actuator ``driven[k]`` by its `step`, action 2k + 1 lowers it.
    Continuous, one value a per driven actuator: the target 0.5 (a + 1) high (``"absolute"``)
    or the command plus ``scale`` a (``"increment"``); the actuators not driven go to 0
    (absolute) or hold (increment). Targets are clipped to [0, high]. ``shared=True``: one
    command for all the actuators (one value pulls every cable), read from the first.
    """

    def __init__(
        self,
        high: np.ndarray,
        *,
        step=1.0,
        mode: Literal["absolute", "increment"] = "absolute",
        scale: float = 1.0,
        driven: np.ndarray | None = None,
        shared: bool = False,
    ) -> None:
        self.high = np.asarray(high, dtype=float)
        self.shared = bool(shared)
        n = 1 if self.shared else len(self.high)
        self.driven = np.arange(n) if driven is None else np.asarray(driven)
        self.mode = mode
        self.scale = float(scale)
        self.table = discrete_increments(n, step)
        self.n_discrete = 2 * len(self.driven)
        self.n_continuous = len(self.driven)

    def _own(self, commands: Commands) -> np.ndarray:
        return commands.actuators[:1] if self.shared else commands.actuators

    def _set(self, commands: Commands, target: np.ndarray) -> Commands:
        high = self.high[:1] if self.shared else self.high
        target = np.clip(target, 0.0, high)
        if self.shared:
            target = np.full(len(commands.actuators), target[0])
        return commands.with_actuators(target)

    def discrete(self, env, action, commands):
        if action is None:
            return commands
        row = 2 * int(self.driven[action // 2]) + action % 2
        return self._set(commands, self._own(commands) + self.table[row])

    def continuous(self, env, action, commands):
        current = self._own(commands)
        if self.mode == "absolute":
            values = np.full(len(current), -1.0)  # not driven: a target of 0
            values[self.driven] = action
            return self._set(commands, 0.5 * (values + 1.0) * self.high[: len(current)])
        values = np.zeros(len(current))  # not driven: no change
        values[self.driven] = action
        return self._set(commands, current + self.scale * values)


class RampTarget(ActionMap):
    """A kinematic input, the ramp `ramp` of the environment, moved over each step towards a
    target in [low, high].

    Discrete: action k adds row k of `steps` to the previous target (``None``, another map's
    action: the target holds). Continuous: the target ``high x a`` (``"scaled"``, a range
    symmetric about 0), ``low + (a + 1) / 2 (high - low)`` (``"interval"``) or the previous
    target plus ``scale x a`` (``"increment"``). The previous target is the task's entry
    `memory` (stored there, as a float for a scalar input), or the ramp's own target. With a
    `speed` (units/s), the ramp moves at most ``speed x step time`` towards the target in a
    step; every step retargets the ramp.
    """

    def __init__(
        self,
        ramp: str,
        low,
        high,
        *,
        steps: np.ndarray,
        continuous: Literal["scaled", "interval", "increment"] = "scaled",
        scale=1.0,
        speed: float | None = None,
        memory: str | None = None,
        size: int = 1,
    ) -> None:
        self.ramp, self.low, self.high = ramp, low, high
        self.steps = np.asarray(steps, dtype=float)
        self.mode = continuous
        self.scale = scale
        self.speed = speed
        self.memory = memory
        self.n_discrete = len(self.steps)
        self.n_continuous = size

    def previous(self, env: SoftRobotEnv):
        return env.task[self.memory] if self.memory else env.ramps[self.ramp].target

    def discrete(self, env, action, commands):
        target = self.previous(env)
        if action is not None:
            target = target + self.steps[action]
        return self._move(env, target, commands)

    def continuous(self, env, action, commands):
        if self.mode == "scaled":
            target = self.high * np.asarray(action, dtype=float)
        elif self.mode == "interval":
            target = in_interval(action, self.low, self.high)
        else:
            target = self.previous(env) + self.increment(action)
        return self._move(env, target, commands)

    def increment(self, action: np.ndarray) -> np.ndarray:
        """The continuous action's change of the target (``"increment"``)."""
        return self.scale * np.asarray(action, dtype=float)

    def _move(self, env, target, commands):
        target = np.clip(target, self.low, self.high)
        remembered = {}
        if self.memory:
            scalar = np.size(target) == 1
            target = float(np.reshape(target, -1)[0]) if scalar else target
            remembered[self.memory] = target
        if self.speed is not None:
            ramp = env.ramps[self.ramp]
            now = (
                ramp.scalar(env.state.time) if np.size(target) == 1 else ramp.value(env.state.time)
            )
            reach = self.speed * env.step_time
            target = now + np.clip(target - now, -reach, reach)
        return commands.with_ramp(self.ramp, target, **remembered)


@dataclass(frozen=True)
class CartDrive:
    """A cart on x driven by position (CartStemContact, CatchTheObject): its target within
    +-``max_move`` mm, reached at most at ``max_speed`` mm/s. The environments take the fields
    as keywords, over their class's ``cart_drive``."""

    max_move: float = 40.0
    max_speed: float = 40.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "max_move", check_positive("max_move", self.max_move))
        object.__setattr__(self, "max_speed", check_positive("max_speed", self.max_speed))

    def actions(self, step_time: float, ramp: str = "cart") -> RampTarget:
        """Discrete, 3 actions (left, stay, right: the target moves by ``max_speed x
        step_time``); continuous, the target ``max_move x a``; remembered in the task's
        ``"target"``."""
        reach = self.max_speed * step_time
        return RampTarget(
            ramp,
            -self.max_move,
            self.max_move,
            steps=[[-reach], [0.0], [reach]],
            speed=self.max_speed,
            memory="target",
        )
