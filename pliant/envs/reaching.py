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

import numpy as np

from pliant.envs.actions import ActionMap, ActuatorTargets
from pliant.envs.base import SoftRobotEnv, progress_reward
from pliant.envs.config import check_choice, check_positive

RewardVariant = Literal["thesis", "sofagym"]
ContinuousMode = Literal["absolute", "increment"]


class CableReachingEnv(SoftRobotEnv):
    """Base of the reaching tasks. Subclasses implement ``_build``, ``_observe``,
    :meth:`effector_position` and :meth:`sofagym_progress`, and set ``observation_space``;
    :meth:`cable_actions` may add to the cables' action map."""

    rewards = ("thesis", "sofagym")

    def __init__(
        self,
        *,
        continuous_mode: ContinuousMode = "absolute",
        action_scale: float = 1.0,
        goal_low,
        goal_high,
        goal_tolerance: float,
        **kwargs,
    ) -> None:
        check_choice("continuous_mode", continuous_mode, ("absolute", "increment"))
        self.action_scale = check_positive("action_scale", action_scale)
        self.goal_tolerance = check_positive("goal_tolerance", goal_tolerance)
        self.continuous_mode = continuous_mode
        self.goal_low = np.asarray(goal_low, dtype=float)
        self.goal_high = np.asarray(goal_high, dtype=float)
        super().__init__(**kwargs)
        self.max_commands = np.array([a.max_displacement for a in self.model.actuators])
        self.use_actions(self.cable_actions())

    def cables(self, driven: np.ndarray | None = None) -> ActuatorTargets:
        """The cables' action map: one pulled or released by ``action_scale`` mm (discrete),
        targets in [0, max] or increments of at most ``action_scale`` (continuous)."""
        return ActuatorTargets(
            self.max_commands,
            step=self.action_scale,
            mode=self.continuous_mode,
            scale=self.action_scale,
            driven=driven,
        )

    def cable_actions(self) -> ActionMap:
        """The task's action map: the cables'."""
        return self.cables()

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
