"""What the cable-driven reaching tasks share (Diamond, Trunk): commands that are the cables'
displacements, a goal for the effector, and the progress reward of thesis Eq. 3.2.

Actions: discrete, one cable pulled or released by ``action_scale`` mm (2 n actions, SofaGym's);
continuous, the n displacements either as targets in [0, max] (``continuous_mode="absolute"``,
the thesis' "cable lengths") or as increments of at most ``action_scale``
(``"increment"``). Reward: Eq. 3.2, max(0, (d_{t-1} - d_t) / d_{t-1}) in [0, 1]
(``reward="thesis"``), or the task's SofaGym variant (``reward="sofagym"``). Terminated when
the effector is within ``goal_tolerance`` mm of the goal, drawn uniformly in
[``goal_low``, ``goal_high``] (or given as ``reset(options={"goal": ...})``).
"""

from __future__ import annotations

from typing import Literal

import gymnasium as gym
import numpy as np

from pliant.envs.base import (
    ActionType,
    SoftRobotEnv,
    discrete_increments,
    progress_reward,
    scaled_box,
)

RewardVariant = Literal["thesis", "sofagym"]
ContinuousMode = Literal["absolute", "increment"]


def check_choice(name: str, value, options: tuple) -> None:
    if value not in options:
        raise ValueError(f"{name} must be one of {options}, got {value!r}")


def check_positive(name: str, value) -> float:
    if not (isinstance(value, int | float | np.number) and np.isfinite(value) and value > 0):
        raise ValueError(f"{name} must be finite and > 0, got {value!r}")
    return float(value)


class CableReachingEnv(SoftRobotEnv):
    """Base of the reaching tasks. Subclasses implement ``_build``, ``_observe``,
    :meth:`effector_position` and :meth:`sofagym_progress`, and set ``observation_space``."""

    def __init__(
        self,
        *,
        dt: float,
        substeps: int,
        action_type: ActionType,
        continuous_mode: ContinuousMode,
        action_scale: float,
        reward: RewardVariant,
        goal_low,
        goal_high,
        goal_tolerance: float,
        render_mode: str | None,
        tangent: str,
    ) -> None:
        check_choice("reward", reward, ("thesis", "sofagym"))
        check_choice("continuous_mode", continuous_mode, ("absolute", "increment"))
        self.action_scale = check_positive("action_scale", action_scale)
        self.goal_tolerance = check_positive("goal_tolerance", goal_tolerance)
        self.continuous_mode = continuous_mode
        self.reward_variant = reward
        self.goal_low = np.asarray(goal_low, dtype=float)
        self.goal_high = np.asarray(goal_high, dtype=float)
        super().__init__(
            dt=dt,
            substeps=substeps,
            action_type=action_type,
            render_mode=render_mode,
            tangent=tangent,
        )
        self.max_commands = np.array([a.max_displacement for a in self.model.actuators])
        n = self.n_actuators
        if action_type == "discrete":
            self._table = discrete_increments(n, self.action_scale)
            self.action_space = gym.spaces.Discrete(2 * n)
        else:
            self.action_space = scaled_box(-1.0, 1.0, (n,))

    def effector_position(self) -> np.ndarray:
        """(3,) the point that must reach the goal."""
        raise NotImplementedError

    def sofagym_progress(self, distance: float) -> float:
        """SofaGym's reward for the new distance (``self.task`` holds the previous ones)."""
        raise NotImplementedError

    def distance(self) -> float:
        return float(np.linalg.norm(self.effector_position() - self.task["goal"]))

    def _reset_task(self, rng, options) -> None:
        goal = (options or {}).get("goal")
        if goal is None:
            goal = rng.uniform(self.goal_low, self.goal_high)
        self.task["goal"] = np.asarray(goal, dtype=float).reshape(3)
        self.task["distance"] = self.task["best"] = self.distance()

    def _commands_from_action(self, action) -> None:
        if self.action_type == "discrete":
            target = self.commands + self._table[action]
        elif self.continuous_mode == "absolute":
            target = 0.5 * (action + 1.0) * self.max_commands
        else:
            target = self.commands + self.action_scale * action
        self.target_commands = np.clip(target, 0.0, self.max_commands)

    def _reward(self):
        d = self.distance()
        if self.reward_variant == "thesis":
            r = progress_reward(self.task["distance"], d)
        else:
            r = self.sofagym_progress(d)
        self.task["distance"] = d
        self.task["best"] = min(self.task["best"], d)
        return r, d <= self.goal_tolerance, {"progress": r}

    def _info(self):
        d = self.task["distance"]
        return {"distance": d, "is_success": d <= self.goal_tolerance}
