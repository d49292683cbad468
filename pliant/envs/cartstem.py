"""CartStemContact (thesis §3.1.2, §3.3.2, §4.2.2; SofaGym cartstemcontact-v0).

A beam standing on a cart between two box obstacles; the cart, position-controlled with a
bounded speed, must bring the beam's tip over a goal on x, which behind an obstacle means
bending the beam over the other one first (the QPCC from rest stalls in a local minimum).

Observation (thesis, Eq. 4.7's state): [x_cart, x_tip, x_left, x_right, l_x, l_z, x_goal]
divided by the beam length (7 values; x_left/x_right the obstacles' centres, l_x, l_z their
size); ``observation="sofagym"`` gives SofaGym's 8: [x_cart, x_tip, x_left, x_right, half
sizes (3), x_goal]. Action: Box(1) in [-1, 1], the cart's target ``max_move * a``, reached at
most at ``max_speed`` (mm/s); ``action_type="discrete"``: 3 actions (left, stay, right: the
target moves by ``max_speed`` x step time). Reward: thesis -|x_tip - x_goal| / length;
``reward="sofagym"``: max(-max_dist, -|x_tip - x_goal|) / max_dist. The cart starts at rest
anywhere in [-cart_range, cart_range] (thesis: random goal and cart), the beam straight and
between the obstacles; ``options={"goal": g, "cart": c}`` pins either. With
``obstacle_shift`` s > 0 the two obstacles move together along x by U(-s, s) each episode and
the cart is drawn within ``cart_range`` of their centre (thesis §4.2.2: random contact and base
positions; ``options={"shift": o}`` pins the shift). Terminated when
|x_tip - x_goal| < ``goal_tolerance`` (thesis: 1 % of the beam's length). 30 steps of
30 x 0.01 s. Goal drawn uniformly on [-goal_range, goal_range].
"""

from __future__ import annotations

import numpy as np

from pliant.envs.actions import CartDrive, scaled_box
from pliant.envs.base import SoftRobotEnv
from pliant.envs.config import EnvConfigError, SimulationConfig, with_keywords
from pliant.model import Model
from pliant.robots.cartstem import cartstem_contact


class CartStemContactEnv(SoftRobotEnv):
    name = "CartStemContact"
    view = (5.0, -90.0)
    default_config = SimulationConfig(substeps=30, action_type="continuous")
    # Released from an obstacle, the beam whips back on its first bending mode (about 7 Hz with
    # the default beam): its tip moves up to 9 mm in a 0.01 s step, three times the robot's
    # default detection margin, and contacts were missed under random policies. 12 mm leaves
    # no warning over random episodes and costs 5 % of the step.
    robot_defaults = {"stem": "tetrahedra", "length": 100.0, "contact_margin": 12.0}
    rewards = observations = ("thesis", "sofagym")
    cart_drive = CartDrive(max_move=40.0, max_speed=40.0)

    def __init__(
        self,
        *,
        goal_range: float = 35.0,
        goal_tolerance: float = 1.0,
        cart_range: float = 10.0,
        obstacle_shift: float = 0.0,
        **kwargs,
    ) -> None:
        self.cart_drive = with_keywords(self.cart_drive, kwargs)
        self.max_move, self.max_speed = self.cart_drive.max_move, self.cart_drive.max_speed
        self.goal_range = float(goal_range)
        self.goal_tolerance = float(goal_tolerance)
        self.cart_range = float(cart_range)
        self.obstacle_shift = float(obstacle_shift)
        super().__init__(**kwargs)
        self.length = float(self.robot_kwargs["length"])
        self.use_actions(self.cart_drive.actions(self.step_time))
        self.observation_space = scaled_box(
            -5.0, 5.0, (7 if self.observation_variant == "thesis" else 8,)
        )
        boxes = self.model.contacts.shapes
        self.obstacles = np.array([b.position for b in boxes])
        self._obstacles_at_rest = self.obstacles.copy()
        self.obstacle_size = 2.0 * np.asarray(boxes[0].half_extents, dtype=float)
        clearance = self.obstacles[1, 0] - 0.5 * self.obstacle_size[0]
        clearance -= float(np.abs(self._initial.positions[:, 0]).max())
        self._clearance = clearance
        if not (np.isfinite(self.cart_range) and 0.0 <= self.cart_range < clearance):
            raise EnvConfigError(
                f"cart_range must be in [0, {clearance:.3g}) (the beam starts between the"
                f" obstacles, clear of them), got {cart_range!r}"
            )
        if not (np.isfinite(self.obstacle_shift) and self.obstacle_shift >= 0.0):
            raise EnvConfigError(f"obstacle_shift must be >= 0 (mm), got {obstacle_shift!r}")

    def _build(self) -> Model:
        self.cart = self.ramp("cart", 0.0)
        return cartstem_contact(cart_motion=self.cart.scalar, **self.robot_kwargs)

    def cart_x(self) -> float:
        return self.cart.scalar(self.state.time)

    def tip_x(self) -> float:
        return float(self.model.effectors[0].position(self.state.positions)[0, 0])

    def _reset_task(self, rng, options) -> None:
        goal = (options or {}).get("goal")
        if goal is None:
            goal = rng.uniform(-self.goal_range, self.goal_range)
        self.task["goal"] = float(goal)
        shift = (options or {}).get("shift")
        if shift is None:
            shift = rng.uniform(-self.obstacle_shift, self.obstacle_shift)
        elif not np.isfinite(shift):
            raise ValueError(f"options['shift'] must be a finite distance (mm), got {shift!r}")
        self.move_obstacles(float(shift))
        cart = (options or {}).get("cart")
        if cart is None:
            cart = shift + rng.uniform(-self.cart_range, self.cart_range)
        elif not (np.isfinite(cart) and abs(cart - shift) < self._clearance):
            raise ValueError(
                f"options['cart'] must be within +-{self._clearance:.3g} mm of the obstacles'"
                f" centre ({shift:.3g} mm: the beam between the obstacles), got {cart!r}"
            )
        # The beam starts straight and at rest on the cart, wherever the cart is.
        self.cart.source[:] = cart
        self.cart.target[:] = cart
        self.model.trajectories_changed()
        self.state.positions[:, 0] += cart
        self.task["target"] = float(cart)

    def move_obstacles(self, shift: float) -> None:
        """Both obstacles `shift` mm along x from where the robot builder put them."""
        self.obstacles = self._obstacles_at_rest + np.array([shift, 0.0, 0.0])
        for box, position in zip(self.model.contacts.shapes, self.obstacles, strict=True):
            box.position[:] = position
        self.task["shift"] = shift

    def set_state(self, snapshot) -> None:
        super().set_state(snapshot)
        self.move_obstacles(self.task.get("shift", 0.0))

    def _observe(self) -> np.ndarray:
        xl, xr = self.obstacles[0, 0], self.obstacles[1, 0]
        size = self.obstacle_size
        if self.observation_variant == "thesis":
            obs = [self.cart_x(), self.tip_x(), xl, xr, size[0], size[2], self.task["goal"]]
        else:
            obs = [self.cart_x(), self.tip_x(), xl, xr, *(0.5 * size), self.task["goal"]]
        return np.asarray(obs) / self.length

    def _reward(self):
        error = abs(self.tip_x() - self.task["goal"])
        if self.reward_variant == "thesis":
            r = -error / self.length
        else:
            r = max(-self.max_move, -error) / self.max_move
        return r, error < self.goal_tolerance, {"distance": r}

    def _render_goal(self):
        tip = self.model.effectors[0].position(self.state.positions)[0]
        return np.array([self.task["goal"], tip[1], tip[2]])

    def _info(self):
        error = abs(self.tip_x() - self.task["goal"])
        return {"distance": error, "is_success": error < self.goal_tolerance}
