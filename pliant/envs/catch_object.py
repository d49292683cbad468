"""CatchTheObject: move a cart so that its pneumatic gripper catches a ball (SofaGym
catchtheobject-v0; not in the thesis).

The scene of :func:`pliant.robots.catch_object.catch_object`: a U-shaped PneuNet gripper on a
cart translating along x, a rigid ball thrown straight up from ``ball_height`` mm at
``throw_speed`` mm/s, its x drawn in [-ball_range, ball_range] each episode (written into the
initial state's rigid bodies). The gripper closes by itself (its chambers ramp to
``grip_pressure`` kPa) once the ball has come down within ``grip_height`` mm of the palm; the
agent moves the cart.

Observation (5 values, SofaGym's size): [cart x, ball x, ball z] divided by
``length_scale``, the ball's vertical speed divided by ``throw_speed`` and the chambers'
pressure divided by its maximum. Action: Box(1) in [-1, 1] (SofaGym's), the cart's target
``max_move x a`` mm, reached at most at ``max_speed`` mm/s; ``action_type="discrete"``: 3
actions (left, stay, right: the target moves by max_speed x step time). Reward (SofaGym's):
-dist / max_dist, dist the distance from the ball to the gripper's catching point (the palm's
top centre lifted by the ball's radius), max_dist its value when the ball is at the start
height, farthest from the cart (the reward clipped at -1). Terminated when the ball falls
below the palm's top (missed). 30 steps of 10 x 0.01 s.
"""

from __future__ import annotations

import numpy as np

from pliant.envs.actions import CartDrive, Commands, scaled_box
from pliant.envs.base import SoftRobotEnv
from pliant.envs.config import SimulationConfig, check_positive, with_keywords
from pliant.model import Model
from pliant.robots.catch_object import catch_object


class CatchTheObjectEnv(SoftRobotEnv):
    name = "CatchTheObject"
    view = (10.0, -80.0)
    default_config = SimulationConfig(substeps=10, action_type="continuous")
    robot_defaults = {"mesh_size": 6.0}
    cart_drive = CartDrive(max_move=40.0, max_speed=100.0)

    def __init__(
        self,
        *,
        ball_range: float = 30.0,
        ball_height: float = 150.0,
        throw_speed: float = 2000.0,
        grip_pressure: float = 30.0,
        grip_height: float = 60.0,
        length_scale: float = 100.0,
        **kwargs,
    ) -> None:
        self.cart_drive = with_keywords(self.cart_drive, kwargs)
        self.max_move, self.max_speed = self.cart_drive.max_move, self.cart_drive.max_speed
        self.throw_speed = check_positive("throw_speed", throw_speed)
        self.ball_range = float(ball_range)
        self.ball_height = float(ball_height)
        self.grip_pressure = float(grip_pressure)
        self.grip_height = float(grip_height)
        self.length_scale = float(length_scale)
        super().__init__(**kwargs)
        self.max_pressure = float(self.model.actuators[0].max_force)
        self.palm_top = float(self.robot_kwargs.get("palm_thickness", 8.0))
        self.radius = float(self.model.rigid_bodies[0].shape.radius)
        self.max_distance = float(
            np.hypot(self.ball_range + self.max_move, self.ball_height - self.palm_top)
        )
        self.use_actions(self.cart_drive.actions(self.step_time))
        self.observation_space = scaled_box(-5.0, 5.0, (5,))

    def _build(self) -> Model:
        self.cart = self.ramp("cart", 0.0)
        return catch_object(
            ball_position=(0.0, 0.0, self.ball_height),
            cart_motion=self.cart.scalar,
            **self.robot_kwargs,
        )

    def _reset_task(self, rng, options) -> None:
        x = (options or {}).get("ball_x")
        if x is None:
            x = rng.uniform(-self.ball_range, self.ball_range)
        self.state.rigid_positions[0, 0] = float(x)
        self.state.rigid_velocities[0] = [0.0, 0.0, self.throw_speed]
        self.task["target"] = 0.0

    def cart_x(self) -> float:
        return self.cart.scalar(self.state.time)

    def ball(self) -> np.ndarray:
        return self.state.rigid_positions[0]

    def distance(self) -> float:
        catch = np.array([self.cart_x(), 0.0, self.palm_top + self.radius])
        return float(np.linalg.norm(self.ball() - catch))

    def _commands(self, action) -> Commands:
        """The cart's, and the gripper, which closes by itself (the chambers to
        ``grip_pressure``) once the ball, coming down, is within ``grip_height`` of the palm,
        and stays closed."""
        coming = self.state.rigid_velocities[0, 2] <= 0.0
        near = self.ball()[2] < self.palm_top + self.grip_height
        grip = self.grip_pressure if (coming and near) or self.commands[0] > 0 else 0.0
        return super()._commands(action).with_actuators(np.array([grip]))

    def _observe(self) -> np.ndarray:
        s = self.length_scale
        ball = self.ball()
        return np.array(
            [
                self.cart_x() / s,
                ball[0] / s,
                ball[2] / s,
                self.state.rigid_velocities[0, 2] / self.throw_speed,
                self.commands[0] / self.max_pressure,
            ]
        )

    def _reward(self):
        r = max(-1.0, -self.distance() / self.max_distance)
        missed = bool(self.ball()[2] < self.palm_top)
        return r, missed, {"distance": r}

    def _info(self):
        caught = bool(
            self.commands[0] > 0
            and abs(self.ball()[0] - self.cart_x()) < self.radius
            and self.ball()[2] < self.palm_top + 2 * self.radius
        )
        return {"distance": self.distance(), "is_success": caught}

    def _render_goal(self):
        return None
