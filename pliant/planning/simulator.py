"""The environment seen by a planner: a deterministic model that can be saved, restored and
stepped.

SofaGym reaches saved configurations through a server of forked worker processes, because SOFA
cannot copy a scene (thesis L365); a Pliant environment hands out its whole state instead
(``env.unwrapped.get_state()``) and takes it back (``set_state``), so a tree node just keeps that
snapshot.

The planner steps ``env.unwrapped``: the snapshot is the unwrapped environment's state, and the
wrappers' own state (``TimeLimit``'s step counter, the order checks) is not in it. Wrappers that
change rewards, observations or actions are therefore not seen by the search; an environment
meant for planning produces its rewards and discrete actions itself.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from pliant.errors import PlanningError


@dataclass(frozen=True, slots=True)
class Transition:
    """What one simulated step returns to the search."""

    reward: float
    done: bool  # terminated or truncated: the episode has no further rewards


class Simulator:
    """Save, restore and step the unwrapped environment, counting the simulated steps.

    Raises:
        PlanningError: the action space is not ``Discrete``, a wrapper changes it, or the
            environment has no ``get_state``/``set_state``.
    """

    def __init__(self, env: Any) -> None:
        from gymnasium import spaces  # the planners' only use of gymnasium, an optional extra

        base = env.unwrapped
        missing = [m for m in ("get_state", "set_state") if not callable(getattr(base, m, None))]
        if missing:
            raise PlanningError(
                f"{type(base).__name__} has no {' or '.join(missing)}: tree search restarts from"
                " saved states, so the environment must hand out and take back a snapshot"
            )
        space = base.action_space
        if not isinstance(space, spaces.Discrete):
            raise PlanningError(
                f"tree search needs a Discrete action space, {type(base).__name__} has {space}"
                " (a Pliant environment takes action_type='discrete')"
            )
        if env.action_space != space:
            raise PlanningError(
                f"a wrapper changes the action space ({space} -> {env.action_space}); the planner"
                " steps env.unwrapped, so the discrete actions must be the environment's own"
            )
        self.env = base
        self.actions: tuple[int, ...] = tuple(int(space.start) + i for i in range(int(space.n)))
        self.steps = 0

    @property
    def n_actions(self) -> int:
        return len(self.actions)

    def save(self) -> object:
        """A snapshot of the current state (the environment must not modify it later)."""
        return self.env.get_state()

    def restore(self, state: object) -> None:
        self.env.set_state(state)

    def step(self, action: int) -> Transition:
        """One simulated step; a non-finite reward is refused (it would poison every bound)."""
        _, reward, terminated, truncated, _ = self.env.step(action)
        self.steps += 1
        reward = float(reward)
        if not math.isfinite(reward):
            raise PlanningError(f"action {action} gave a non-finite reward {reward}")
        return Transition(reward, bool(terminated or truncated))


def check_restorable(env: Any, actions: Sequence[int]) -> None:
    """Check the determinism the planners rely on: from the current state, play ``actions``,
    restore the state, play them again; every observation, reward and end flag must be equal bit
    for bit. The environment is left in the state it started from.

    Raises:
        PlanningError: at the first step that differs, naming it.
    """
    sim = Simulator(env)
    start = sim.save()
    try:
        first = [sim.env.step(a)[:4] for a in actions]
        sim.restore(start)
        for i, (a, expected) in enumerate(zip(actions, first, strict=True)):
            again = sim.env.step(a)[:4]
            names = ("observation", "reward", "terminated", "truncated")
            for name, x, y in zip(names, expected, again, strict=True):
                if not _equal(x, y):
                    raise PlanningError(
                        f"restoring the state does not reproduce the run: step {i} (action {a})"
                        f" gave the {name} {y!r} after restoring and {x!r} before"
                    )
    finally:
        sim.restore(start)


def _equal(x: object, y: object) -> bool:
    """Bitwise equality of observations, which may be arrays, numbers or dicts/tuples of them."""
    if isinstance(x, Mapping):
        return (
            isinstance(y, Mapping) and x.keys() == y.keys() and all(_equal(x[k], y[k]) for k in x)
        )
    if isinstance(x, tuple | list):
        return (
            isinstance(y, tuple | list)
            and len(x) == len(y)
            and all(_equal(a, b) for a, b in zip(x, y, strict=True))
        )
    return np.array_equal(np.asarray(x), np.asarray(y))
