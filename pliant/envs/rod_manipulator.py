"""RodManipulator: two soft fingers turn a rod on a table to a goal angle (thesis §4.2.2,
Fig. 4.8 B; the configuration-space paper's BarManipulator).

The scene of :func:`pliant.robots.rod_manipulator.rod_manipulator`: two fingers of 4 cables
each (bending towards +x, +y, -x, -y) hang from a base translating vertically, over a square
rod lying on the table. The rod's angle about the vertical is accumulated over the episode
(unwrapped), so that turns beyond 180 degrees count.

Observation (thesis: "3 points at the end of each finger, position and orientation of the rod
centre, target orientation"; authors' code, 23 values): 3 points at each fingertip (its centre
and 3 mm towards +x and +y), the rod's centre, divided by ``length_scale``, the cumulative
angle and the goal angle divided by 2 pi. Action: continuous (authors' Box(9)), the 8 cables'
targets in [0, max] and the base's height offset in [base_low, base_high] mm; discrete: 18
actions, one cable pulled or released by ``action_scale`` mm, the base lowered or raised by
``base_step`` mm. (The authors' fingers have two segments, an end part and a top part bending
in 2 directions each; Pliant's fingers are one segment of 4 cables, hence 8 cable commands
rather than 4 bendings per finger.) Reward: thesis "normalised angle covered by the bar",
-|goal - angle| / goal (``reward="thesis"``); the authors' code (``"sofagym"``):
3 (-|goal - angle| / goal) + 1/4 sum_f min(0, (30 - d_f) / 30), d_f the distance (mm) from
finger f's tip to the rod's centre. Terminated when |goal - angle| < ``goal_tolerance`` (rad).
Goal angle drawn uniformly in [goal_low, goal_high] rad (authors': (initial, 360 degrees)).
30 steps of 10 x 0.01 s.
"""

from __future__ import annotations

import numpy as np

from pliant.constraints.base import EmbeddedPoints
from pliant.envs.actions import ActuatorTargets, RampTarget, scaled_box
from pliant.envs.base import SoftRobotEnv
from pliant.envs.config import SimulationConfig, check_interval
from pliant.model import Model
from pliant.robots.rod_manipulator import rod_angle, rod_manipulator


class RodManipulatorEnv(SoftRobotEnv):
    name = "RodManipulator"
    view = (45.0, -30.0)
    default_config = SimulationConfig(substeps=10, action_type="continuous")
    robot_defaults = {"mesh_size": 4.0}
    rewards = ("thesis", "sofagym")

    def __init__(
        self,
        *,
        action_scale: float = 1.0,
        base_low: float = -10.0,
        base_high: float = 5.0,
        base_step: float = 1.0,
        goal_low: float = np.radians(20.0),
        goal_high: float = 2.0 * np.pi,
        goal_tolerance: float = np.radians(5.0),
        length_scale: float = 50.0,
        **kwargs,
    ) -> None:
        check_interval("base", base_low, base_high, contains=0.0)
        check_interval("goal", goal_low, goal_high, floor=0.0)
        self.action_scale = float(action_scale)
        self.base_low, self.base_high = float(base_low), float(base_high)
        self.base_step = float(base_step)
        self.goal_low, self.goal_high = float(goal_low), float(goal_high)
        self.goal_tolerance = float(goal_tolerance)
        self.length_scale = float(length_scale)
        super().__init__(**kwargs)
        self.max_commands = np.array([a.max_displacement for a in self.model.actuators])
        cables = ActuatorTargets(self.max_commands, step=self.action_scale)
        steps = [[self.base_step], [-self.base_step]]
        base = RampTarget(
            "base", self.base_low, self.base_high, steps=steps, continuous="interval", memory="base"
        )
        self.use_actions(cables + base)
        self.observation_space = scaled_box(-5.0, 5.0, (23,))

    def _build(self) -> Model:
        self.base = self.ramp("base", 0.0)
        model = rod_manipulator(base_motion=self.base.scalar, **self.robot_kwargs)
        # 3 points at each fingertip: its centre and 3 mm towards +x and +y, 1 mm up.
        tips = np.vstack([e.points.positions(model.body.rest_positions) for e in model.effectors])
        offsets = np.array([[0.0, 0.0, 1.0], [3.0, 0.0, 1.0], [0.0, 3.0, 1.0]])
        self.tip_points = EmbeddedPoints(
            model.body.mesh, (tips[:, None, :] + offsets[None]).reshape(-1, 3)
        )
        return model

    def rod(self) -> np.ndarray:
        return self.state.rigid_positions[0]

    def _reset_task(self, rng, options) -> None:
        goal = (options or {}).get("goal")
        if goal is None:
            goal = rng.uniform(self.goal_low, self.goal_high)
        self.task["goal"] = float(goal)
        self.task["heading"] = rod_angle(self.state.rigid_rotations[0])
        self.task["angle"] = 0.0
        self.task["base"] = 0.0

    def _turn(self) -> None:
        """Accumulate the rod's turn since the last step (unwrapped: a step turns it by less
        than pi)."""
        heading = rod_angle(self.state.rigid_rotations[0])
        change = (heading - self.task["heading"] + np.pi) % (2.0 * np.pi) - np.pi
        self.task["angle"] += float(change)
        self.task["heading"] = heading

    def _observe(self) -> np.ndarray:
        self._turn()  # idempotent: a second call in the same state adds nothing
        points = self.tip_points.positions(self.state.positions).ravel()
        angles = np.array([self.task["angle"], self.task["goal"]]) / (2.0 * np.pi)
        return np.concatenate([points / self.length_scale, self.rod() / self.length_scale, angles])

    def _reward(self):
        goal, angle = self.task["goal"], self.task["angle"]
        error = abs(goal - angle)
        parts = {"angle": -error / goal}
        if self.reward_variant == "sofagym":
            parts["angle"] *= 3.0
            tips = np.vstack([e.position(self.state.positions)[0] for e in self.model.effectors])
            d = np.linalg.norm(tips - self.rod(), axis=1)
            parts["fingers"] = 0.25 * float(np.minimum(0.0, (30.0 - d) / 30.0).sum())
        return sum(parts.values()), error < self.goal_tolerance, parts

    def _info(self):
        return {
            "angle": self.task["angle"],
            "is_success": abs(self.task["goal"] - self.task["angle"]) < self.goal_tolerance,
        }

    def _render_goal(self):
        return None
