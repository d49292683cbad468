"""TrunkCup: the Trunk drags a cup along the floor to a goal (thesis §3.3.2, Fig. 3.13;
SofaGym trunkcup-v0).

The scene of :func:`pliant.robots.trunk_cup.trunk_cup` (the Trunk lying along +z under gravity
-y, a rigid cup standing on the floor under its distal part), the carriage held still. The
thesis handles the cup with the QPCC and gives no learning definition; SofaGym's is followed,
with the thesis' Trunk reward as the default.

Observation: ``n_points`` points along the neutral fibre, the cup's centre and the goal, divided
by the trunk's length (20 + 1 + 1 points = 66 values, SofaGym's size). Action: the Trunk's
(:class:`pliant.envs.trunk.TrunkEnv`): discrete, one cable pulled or released by
``action_scale`` mm (16 actions, SofaGym's); continuous, the 8 cables as targets in [0, max]
(``"absolute"``) or increments (``"increment"``). Reward: Eq. 3.2 on the cup's distance to the
goal (``reward="thesis"``, in [0, 1]); SofaGym's (``"sofagym"``): (d_0 - |c - g|_1) / d_0
with d_0 the initial L1 distance (SofaGym leaves it in mm), plus 1 on success. Terminated
when the cup's centre is within ``goal_tolerance`` mm (3, SofaGym's) of the goal. The goal
lies on the floor at the cup's start plus an offset drawn in [goal_low, goal_high] (x, z),
towards the carriage, where curling the trunk over the cup's far wall drags it. 250 steps of
5 x 0.01 s. The trunk starts settled under gravity over the cup.
"""

from __future__ import annotations

import numpy as np

from pliant.envs.actions import scaled_box
from pliant.envs.base import floor_goal, progress_reward
from pliant.envs.trunk import TrunkEnv
from pliant.robots.trunk_cup import trunk_cup


def _still(t: float) -> float:
    return 0.0


class TrunkCupEnv(TrunkEnv):
    name = "TrunkCup"
    view = (25.0, -40.0)
    robot_defaults = {"mesh_size": 8.0, "base_motion": _still}
    builder = staticmethod(trunk_cup)

    def __init__(
        self,
        *,
        goal_low: tuple[float, float] = (-15.0, -45.0),
        goal_high: tuple[float, float] = (15.0, -10.0),
        goal_tolerance: float = 3.0,
        n_points: int = 20,
        settle_steps: int = 30,
        **kwargs,
    ) -> None:
        super().__init__(
            goal_low=goal_low,
            goal_high=goal_high,
            goal_tolerance=goal_tolerance,
            n_points=n_points,
            settle_steps=settle_steps,
            **kwargs,
        )
        self.observation_space = scaled_box(-3.0, 3.0, (3 * (self.n_points + 2),))

    def cup(self) -> np.ndarray:
        return self.state.rigid_positions[0]

    def distance(self) -> float:
        return float(np.linalg.norm(self.cup() - self.task["goal"]))

    def _reset_task(self, rng, options) -> None:
        self.task["goal"] = floor_goal(rng, options, self.cup(), self.goal_low, self.goal_high)
        self.task["distance"] = self.distance()
        self.task["l1"] = float(np.abs(self.cup() - self.task["goal"]).sum())

    def _observe(self) -> np.ndarray:
        return self.fibre_observation(self.cup(), self.task["goal"])

    def _reward(self):
        d, previous = self.distance(), self.task["distance"]
        self.task["distance"] = d
        success = d <= self.goal_tolerance
        if self.reward_variant == "thesis":
            r = progress_reward(previous, d)
            return r, success, {"progress": r}
        d0 = max(self.task["l1"], 1e-9)
        closer = (d0 - float(np.abs(self.cup() - self.task["goal"]).sum())) / d0
        bonus = 1.0 if success else 0.0
        return closer + bonus, success, {"closer": closer, "success": bonus}
