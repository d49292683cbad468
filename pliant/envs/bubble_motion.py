"""BubbleMotion: steer a ball on a soft board with 9 pressure bubbles (SofaGym
bubblemotion-v0; not in the thesis).

The scene of :func:`pliant.robots.bubble_motion.bubble_motion`: a board held by its underside,
nine cavities in a 3 x 3 grid under its top skin, a rigid ball on top. The ball starts at rest
at a random (x, y) in [-ball_range, ball_range]^2 (written into the initial state), the goal is
drawn at ``goal_distance`` = U(goal_low, goal_high) mm from it, in a random direction, inside
the board.

Observation (15 values, SofaGym's size): the ball's centre and the goal (at the ball's height)
divided by half the board's size, and the nine pressures divided by their maximum. Action:
Box(9) in [-1, 1] (SofaGym's), the pressures (a + 1) / 2 x max (ramped over the sub-steps);
``action_type="discrete"``: 18 actions, one cavity's pressure raised or lowered by
``action_scale`` x max. Reward (SofaGym's): -dist / dist_0, dist the ball-goal distance in the
board's plane and dist_0 its value at the start. Terminated when dist < ``goal_tolerance`` (6
mm, SofaGym's 0.6) or the ball leaves the board. 20 steps of 20 x 0.01 s.
"""

from __future__ import annotations

import numpy as np

from pliant.envs.actions import ActuatorTargets, scaled_box
from pliant.envs.base import SoftRobotEnv
from pliant.envs.config import SimulationConfig, check_interval
from pliant.model import Model
from pliant.robots.bubble_motion import bubble_motion


class BubbleMotionEnv(SoftRobotEnv):
    name = "BubbleMotion"
    view = (45.0, -60.0)
    default_config = SimulationConfig(substeps=20, action_type="continuous")
    robot_defaults = {"size": 60.0, "mesh_size": 5.0, "top_mesh_size": 2.0}

    def __init__(
        self,
        *,
        action_scale: float = 0.25,
        ball_range: float = 12.0,
        goal_low: float = 10.0,
        goal_high: float = 20.0,
        goal_tolerance: float = 6.0,
        **kwargs,
    ) -> None:
        check_interval("goal", goal_low, goal_high, floor=0.0)
        self.action_scale = float(action_scale)
        self.ball_range = float(ball_range)
        self.goal_low, self.goal_high = float(goal_low), float(goal_high)
        self.goal_tolerance = float(goal_tolerance)
        super().__init__(**kwargs)
        self.half = 0.5 * float(self.robot_kwargs["size"])
        self.max_pressure = np.array([a.max_force for a in self.model.actuators])
        step = self.action_scale * self.max_pressure
        self.use_actions(ActuatorTargets(self.max_pressure, step=step))
        self.observation_space = scaled_box(-3.0, 3.0, (15,))

    def _build(self) -> Model:
        return bubble_motion(**self.robot_kwargs)

    def ball(self) -> np.ndarray:
        return self.state.rigid_positions[0]

    def distance(self) -> float:
        return float(np.linalg.norm((self.ball() - self.task["goal"])[:2]))

    def _reset_task(self, rng, options) -> None:
        options = options or {}
        start = options.get("ball")
        if start is None:
            start = rng.uniform(-self.ball_range, self.ball_range, 2)
        self.state.rigid_positions[0, :2] = np.asarray(start, dtype=float).reshape(2)
        goal = options.get("goal")
        if goal is None:
            # A direction that keeps the goal on the board (a ball radius from its edges).
            reach = self.half - float(self.model.rigid_bodies[0].shape.radius)
            distance = rng.uniform(self.goal_low, self.goal_high)
            for _ in range(100):
                angle = rng.uniform(0.0, 2.0 * np.pi)
                goal = self.ball()[:2] + distance * np.array([np.cos(angle), np.sin(angle)])
                if np.all(np.abs(goal) <= reach):
                    break
            goal = np.clip(goal, -reach, reach)
        self.task["goal"] = np.array([*np.asarray(goal, dtype=float).reshape(2), self.ball()[2]])
        self.task["d0"] = max(self.distance(), 1e-9)

    def _observe(self) -> np.ndarray:
        return np.concatenate(
            [
                self.ball() / self.half,
                self.task["goal"] / self.half,
                self.commands / self.max_pressure,
            ]
        )

    def _reward(self):
        d = self.distance()
        off = bool(np.any(np.abs(self.ball()[:2]) > self.half))
        r = -d / self.task["d0"]
        return r, off or d < self.goal_tolerance, {"distance": r}

    def _info(self):
        d = self.distance()
        return {"distance": d, "is_success": d < self.goal_tolerance}
