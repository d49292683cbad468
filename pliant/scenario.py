"""Scripted and inverse-controlled runs of a robot, shared by the CLI, examples and tests."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass

import numpy as np

from pliant.constraints.control import InverseControl
from pliant.model import Model, State


def scripted(
    solver, state: State, actuation: Callable[[float], np.ndarray], n_steps: int
) -> Iterator[State]:
    """Yield the states of n_steps steps with commands actuation(t) at the start of each step."""
    for _ in range(n_steps):
        state = solver.step(state, actuation(state.time))
        yield state


@dataclass
class GoalResult:
    goal: np.ndarray
    reached: np.ndarray
    steps: int
    actuation: np.ndarray

    @property
    def error(self) -> float:
        return float(np.linalg.norm(self.reached - self.goal))


def track_goals(
    model: Model,
    solver,
    state: State,
    goals: np.ndarray,
    *,
    max_steps: int = 50,
    tolerance: float = 0.05,
    on_step: Callable[[State, np.ndarray], None] | None = None,
) -> tuple[list[GoalResult], State]:
    """Closed-loop inverse control of the model's first effector through a sequence of goals.

    Each step solves the inverse QP at the current configuration (Eq. 2.15) and applies the
    forces; the loop moves to the next goal when the effector has settled (moved less than
    `tolerance` in a step) or after `max_steps` steps.
    """
    effector = model.effectors[0]
    results = []
    for goal in np.atleast_2d(goals):
        control = InverseControl(goals=[goal[None, :]])
        previous = effector.position(state.positions)[0]
        for k in range(1, max_steps + 1):  # noqa: B007 (k is reported after the loop)
            state = solver.step(state, control)
            now = effector.position(state.positions)[0]
            if on_step is not None:
                on_step(state, goal)
            if np.linalg.norm(now - previous) < tolerance:
                break
            previous = now
        results.append(GoalResult(goal, now, k, state.actuation.copy()))
    return results, state
