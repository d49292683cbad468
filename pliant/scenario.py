"""Scripted and inverse-controlled runs of a robot, shared by the CLI, examples and tests."""

from __future__ import annotations

import warnings
from collections.abc import Callable, Iterator
from dataclasses import dataclass

import numpy as np

from pliant.constraints.control import InverseControl
from pliant.errors import UnreachableGoalWarning
from pliant.model import Model, State


def scripted(
    solver, state: State, actuation: Callable[[float], np.ndarray], n_steps: int
) -> Iterator[State]:
    """Yield the states of n_steps steps with commands actuation(t) at the start of each step."""
    for _ in range(n_steps):
        state = solver.step(state, actuation(state.time))
        yield state


STALL_STEPS = 10  # steps without progress towards a goal after which track_goals moves on


@dataclass
class GoalResult:
    """Where the effector went for one goal. `out_of_reach`: it settled (the closest
    configuration the actuators' bounds allow) farther than the reach tolerance from it."""

    goal: np.ndarray
    reached: np.ndarray
    steps: int
    actuation: np.ndarray
    out_of_reach: bool = False

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
    reach: float | None = None,
    on_step: Callable[[State, np.ndarray], None] | None = None,
) -> tuple[list[GoalResult], State]:
    """Closed-loop inverse control of the model's first effector through a sequence of goals.

    Each step solves the inverse QP at the current configuration (Eq. 2.15) and applies the
    forces; the loop moves to the next goal when the effector has settled (moved less than
    `tolerance` in a step) or after `max_steps` steps. A goal out of reach gives the closest
    configuration the actuators' bounds allow (the QP's least squares); a far goal can also
    make the effector swing about it, so the loop also moves on once the distance to the goal
    has not improved by `tolerance` in STALL_STEPS steps. Where the effector settled or
    stalled farther than `reach` (default 10 x `tolerance`) from its goal, the result says
    `out_of_reach` and an UnreachableGoalWarning names the goal and the distance left.
    """
    reach = 10.0 * tolerance if reach is None else reach
    effector = model.effectors[0]
    results = []
    for goal in np.atleast_2d(goals):
        control = InverseControl(goals=[goal[None, :]])
        previous = effector.position(state.positions)[0]
        best, since = np.inf, 0
        for k in range(1, max_steps + 1):  # noqa: B007 (k is reported after the loop)
            state = solver.step(state, control)
            now = effector.position(state.positions)[0]
            if on_step is not None:
                on_step(state, goal)
            error = float(np.linalg.norm(now - goal))
            best, since = (error, 0) if error < best - tolerance else (best, since + 1)
            settled = bool(np.linalg.norm(now - previous) < tolerance)
            stalled = since >= STALL_STEPS and error > reach
            if settled or stalled:
                break
            previous = now
        far = error > reach and (settled or stalled)
        if far:
            warnings.warn(
                f"goal {np.round(goal, 3).tolist()} is out of reach: the effector ended at"
                f" {np.round(now, 3).tolist()}, {error:.3g} away, about the closest"
                " configuration within the actuators' bounds",
                UnreachableGoalWarning,
                stacklevel=2,
            )
        results.append(GoalResult(goal, now, k, state.actuation.copy(), far))
    return results, state
