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

import numpy as np

from pliant.envs.actions import scaled_box
from pliant.envs.config import check_positive
from pliant.envs.reaching import CableReachingEnv
from pliant.model import Model
from pliant.robots.diamond import diamond


class DiamondEnv(CableReachingEnv):
    name = "Diamond"
    view = (20.0, -60.0)
    robot_defaults = {"mesh_size": 13.0}

    def __init__(
        self,
        *,
        goal_low: tuple[float, float, float] = (-30.0, -30.0, 125.0),
        goal_high: tuple[float, float, float] = (30.0, 30.0, 145.0),
        goal_tolerance: float = 5.0,
        length_scale: float = 100.0,
        **kwargs,
    ) -> None:
        self.length_scale = check_positive("length_scale", length_scale)
        super().__init__(
            goal_low=goal_low, goal_high=goal_high, goal_tolerance=goal_tolerance, **kwargs
        )
        self.observation_space = scaled_box(-5.0, 5.0, (18,))

    def _build(self) -> Model:
        return diamond(**self.robot_kwargs)

    def effector_position(self) -> np.ndarray:
        return self.model.effectors[0].position(self.state.positions)[0]

    def sofagym_progress(self, distance: float) -> float:
        """min(3 sqrt(max((d_best - d) / d_best, 0)), 1), d_best the smallest distance yet."""
        best = self.task["best"]
        return min(3.0 * np.sqrt(max((best - distance) / best, 0.0)), 1.0) if best > 0 else 0.0

    def _observe(self) -> np.ndarray:
        x = self.state.positions
        elbows = [a.points.positions(x)[0] for a in self.model.actuators]
        pts = np.vstack([self.effector_position(), *elbows, self.task["goal"]])
        return (pts / self.length_scale).ravel()
