"""CartStem: keep a soft stem up on a moving cart (SofaGym cartstem-v0; not in the thesis).

The scene of :func:`pliant.robots.cartstem.cartstem`: a Cosserat rod standing on a cart that
translates along x, no obstacle. The stem is soft (its upright position is stable, but barely:
it sways far when the cart accelerates); the agent accelerates the cart as the cart-pole's
force does.

Observation (4 values, SofaGym's size): [cart x, cart velocity, tip x - cart x, tip velocity
along x], positions divided by the stem's length, velocities by ``velocity_scale`` mm/s.
Action: Discrete(2) (SofaGym's): the cart's velocity changes by -/+ ``acceleration`` x step
time each step (the cart then moves at that velocity over the step); continuous: Box(1) in
[-1, 1], the velocity change a x acceleration x step time. The episode starts with the cart's
velocity drawn in +-``initial_speed`` mm/s. Reward: +1 per step. Terminated when |tip x - cart
x| > ``tip_threshold`` mm or the cart leaves [-max_position, max_position]. 80 steps of
10 x 0.01 s.
"""

from __future__ import annotations

import numpy as np

from pliant.envs.actions import ActionMap, scaled_box
from pliant.envs.base import SoftRobotEnv
from pliant.envs.config import SimulationConfig, check_positive
from pliant.model import Model
from pliant.robots.cartstem import cartstem


class CartAcceleration(ActionMap):
    """The cart's velocity (the task's ``"speed"``) changed by a x `acceleration` x step time,
    a = -1 or +1 (discrete) or in [-1, 1]; the cart moves at that velocity over the step."""

    n_discrete = 2
    n_continuous = 1

    def __init__(self, acceleration: float) -> None:
        self.acceleration = acceleration

    def discrete(self, env, action, commands):
        return self._accelerate(env, 2.0 * action - 1.0, commands)

    def continuous(self, env, action, commands):
        return self._accelerate(env, float(action[0]), commands)

    def _accelerate(self, env, a: float, commands):
        speed = env.task["speed"] + a * self.acceleration * env.step_time
        now = env.ramps["cart"].scalar(env.state.time)
        return commands.with_ramp("cart", now + speed * env.step_time, speed=speed)


class CartStemEnv(SoftRobotEnv):
    name = "CartStem"
    view = (5.0, -90.0)
    default_config = SimulationConfig(substeps=10)
    robot_defaults = {"stem": "rod", "length": 100.0, "young_modulus": 300.0}

    def __init__(
        self,
        *,
        acceleration: float = 500.0,
        initial_speed: float = 50.0,
        tip_threshold: float = 15.0,
        max_position: float = 100.0,
        velocity_scale: float = 200.0,
        **kwargs,
    ) -> None:
        self.acceleration = check_positive("acceleration", acceleration)
        self.tip_threshold = check_positive("tip_threshold", tip_threshold)
        self.initial_speed = float(initial_speed)
        self.max_position = float(max_position)
        self.velocity_scale = float(velocity_scale)
        super().__init__(**kwargs)
        self.length = float(self.robot_kwargs["length"])
        self.use_actions(CartAcceleration(self.acceleration))
        self.observation_space = scaled_box(-10.0, 10.0, (4,))

    def _build(self) -> Model:
        self.cart = self.ramp("cart", 0.0)
        return cartstem(cart_motion=self.cart.scalar, **self.robot_kwargs)

    def _reset_task(self, rng, options) -> None:
        speed = (options or {}).get("speed")
        if speed is None:
            speed = rng.uniform(-self.initial_speed, self.initial_speed)
        self.task["speed"] = float(speed)
        # The stem starts upright and still; the cart leaves at that speed in the first step.

    def cart_x(self) -> float:
        return self.cart.scalar(self.state.time)

    def tip(self) -> tuple[float, float]:
        """(x, velocity along x) of the stem's tip."""
        tip = self.model.effectors[0].points
        x = tip.positions(self.state.positions)[0, 0]
        return float(x), float(tip.positions(self.state.velocities)[0, 0])

    def _observe(self) -> np.ndarray:
        x, v = self.tip()
        cart = self.cart_x()
        return np.array(
            [
                cart / self.length,
                self.task["speed"] / self.velocity_scale,
                (x - cart) / self.length,
                v / self.velocity_scale,
            ]
        )

    def _reward(self):
        x, _ = self.tip()
        fallen = abs(x - self.cart_x()) > self.tip_threshold
        out = abs(self.cart_x()) > self.max_position
        return 1.0, fallen or out, {"alive": 1.0}

    def _info(self):
        x, _ = self.tip()
        return {"tip_offset": x - self.cart_x()}

    def _render_goal(self):
        return None
