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

from typing import Literal

import numpy as np

from pliant.envs.base import ActionType, progress_reward, scaled_box
from pliant.envs.trunk import LENGTH, TrunkEnv, neutral_fibre
from pliant.model import Model
from pliant.robots.trunk_cup import trunk_cup


class TrunkCupEnv(TrunkEnv):
    name = "TrunkCup"
    version = 1
    view = (25.0, -40.0)

    def __init__(
        self,
        *,
        dt: float = 0.01,
        substeps: int = 5,
        action_type: ActionType = "discrete",
        continuous_mode: Literal["absolute", "increment"] = "absolute",
        action_scale: float = 1.0,
        reward: Literal["thesis", "sofagym"] = "thesis",
        goal_low: tuple[float, float] = (-15.0, -45.0),
        goal_high: tuple[float, float] = (15.0, -10.0),
        goal_tolerance: float = 3.0,
        n_points: int = 20,
        settle_steps: int = 30,
        mesh_size: float = 8.0,
        render_mode: str | None = None,
        tangent: str = "lagged",
        **robot_kwargs,
    ) -> None:
        super().__init__(
            dt=dt,
            substeps=substeps,
            action_type=action_type,
            continuous_mode=continuous_mode,
            action_scale=action_scale,
            reward=reward,
            goal_low=goal_low,
            goal_high=goal_high,
            goal_tolerance=goal_tolerance,
            n_points=n_points,
            settle_steps=settle_steps,
            mesh_size=mesh_size,
            render_mode=render_mode,
            tangent=tangent,
            **robot_kwargs,
        )
        self.observation_space = scaled_box(-3.0, 3.0, (3 * (self.n_points + 2),))

    def _build(self) -> Model:
        model = trunk_cup(mesh_size=self.mesh_size, base_motion=_still, **self.robot_kwargs)
        self.fibre = neutral_fibre(model, self.n_points)
        return model

    def cup(self) -> np.ndarray:
        return self.state.rigid_positions[0]

    def distance(self) -> float:
        return float(np.linalg.norm(self.cup() - self.task["goal"]))

    def _reset_task(self, rng, options) -> None:
        goal = (options or {}).get("goal")
        if goal is None:
            x, z = rng.uniform(self.goal_low, self.goal_high)
            goal = self.cup() + [x, 0.0, z]
        self.task["goal"] = np.asarray(goal, dtype=float).reshape(3)
        self.task["distance"] = self.distance()
        self.task["l1"] = float(np.abs(self.cup() - self.task["goal"]).sum())

    def _observe(self) -> np.ndarray:
        pts = np.vstack([self.fibre.positions(self.state.positions), self.cup(), self.task["goal"]])
        return (pts / LENGTH).ravel()

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


def _still(t: float) -> float:
    return 0.0
