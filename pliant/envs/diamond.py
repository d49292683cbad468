"""Diamond positioning (thesis §3.1.2, Table 3.1; SofaGym diamondrobot-v0).

Observation: the effector (top point), the four elbows (the cables' attachment points) and the
goal, in mm divided by ``length_scale`` (18 values). Action: discrete, one cable pulled or
released by ``action_scale`` mm (8 actions, SofaGym's); continuous, the four cable
displacements, either as targets in [0, max] (``continuous_mode="absolute"``, the thesis'
"cable lengths") or as increments of at most ``action_scale`` (``"increment"``). Reward:
Eq. 3.2, max(0, (d_{t-1} - d_t) / d_{t-1}) in [0, 1] (``reward="thesis"``), or SofaGym's
min(3 sqrt(max((d_best - d) / d_best, 0)), 1) with d_best the smallest distance so far
(``reward="sofagym"``). The episode ends (terminated) when the effector is within
``goal_tolerance`` mm of the goal; 50 steps of 5 x 0.01 s by default (TimeLimit).
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
from pliant.model import Model
from pliant.robots.diamond import diamond


class DiamondEnv(SoftRobotEnv):
    name = "Diamond"
    version = 1
    view = (20.0, -60.0)

    def __init__(
        self,
        *,
        dt: float = 0.01,
        substeps: int = 5,
        action_type: ActionType = "discrete",
        continuous_mode: Literal["absolute", "increment"] = "absolute",
        action_scale: float = 1.0,
        reward: Literal["thesis", "sofagym"] = "thesis",
        goal_low: tuple[float, float, float] = (-30.0, -30.0, 125.0),
        goal_high: tuple[float, float, float] = (30.0, 30.0, 145.0),
        goal_tolerance: float = 5.0,
        length_scale: float = 100.0,
        mesh_size: float = 13.0,
        render_mode: str | None = None,
        tangent: str = "lagged",
        **robot_kwargs,
    ) -> None:
        if reward not in ("thesis", "sofagym"):
            raise ValueError(f"reward must be 'thesis' or 'sofagym', got {reward!r}")
        if continuous_mode not in ("absolute", "increment"):
            raise ValueError(
                f"continuous_mode must be 'absolute' or 'increment', got {continuous_mode!r}"
            )
        if not (np.isfinite(action_scale) and action_scale > 0):
            raise ValueError(f"action_scale must be > 0, got {action_scale!r}")
        self.mesh_size = mesh_size
        self.robot_kwargs = robot_kwargs
        self.continuous_mode = continuous_mode
        self.action_scale = float(action_scale)
        self.reward_variant = reward
        self.goal_low = np.asarray(goal_low, dtype=float)
        self.goal_high = np.asarray(goal_high, dtype=float)
        self.goal_tolerance = float(goal_tolerance)
        self.length_scale = float(length_scale)
        super().__init__(
            dt=dt,
            substeps=substeps,
            action_type=action_type,
            render_mode=render_mode,
            tangent=tangent,
        )
        self.max_commands = np.array([a.max_displacement for a in self.model.actuators])
        if action_type == "discrete":
            self._table = discrete_increments(4, self.action_scale)
            self.action_space = gym.spaces.Discrete(8)
        else:
            self.action_space = scaled_box(-1.0, 1.0, (4,))
        self.observation_space = scaled_box(-5.0, 5.0, (18,))

    def _build(self) -> Model:
        return diamond(mesh_size=self.mesh_size, **self.robot_kwargs)

    def _reset_task(self, rng, options) -> None:
        goal = (options or {}).get("goal")
        if goal is None:
            goal = rng.uniform(self.goal_low, self.goal_high)
        self.task["goal"] = np.asarray(goal, dtype=float).reshape(3)
        d = self.distance()
        self.task["distance"] = d
        self.task["best"] = d

    def effector(self) -> np.ndarray:
        return self.model.effectors[0].position(self.state.positions)[0]

    def distance(self) -> float:
        return float(np.linalg.norm(self.effector() - self.task["goal"]))

    def _commands_from_action(self, action) -> None:
        if self.action_type == "discrete":
            target = self.commands + self._table[action]
        elif self.continuous_mode == "absolute":
            target = 0.5 * (action + 1.0) * self.max_commands
        else:
            target = self.commands + self.action_scale * action
        self.target_commands = np.clip(target, 0.0, self.max_commands)

    def _observe(self) -> np.ndarray:
        x = self.state.positions
        elbows = [a.points.positions(x)[0] for a in self.model.actuators]
        pts = np.vstack([self.effector(), *elbows, self.task["goal"]])
        return (pts / self.length_scale).ravel()

    def _reward(self):
        d = self.distance()
        if self.reward_variant == "thesis":
            r = progress_reward(self.task["distance"], d)
        else:
            best = self.task["best"]
            r = min(3.0 * np.sqrt(max((best - d) / best, 0.0)), 1.0) if best > 0 else 0.0
            self.task["best"] = min(best, d)
        self.task["distance"] = d
        return r, d <= self.goal_tolerance, {"progress": r}

    def _info(self):
        return {
            "distance": self.task["distance"],
            "is_success": self.task["distance"] <= self.goal_tolerance,
        }
