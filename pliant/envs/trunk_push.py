"""TrunkPush: the Trunk on a translating base pushes a cube on a plane to a goal (thesis
§4.1.2, §4.1.3: the proxy chapter's task, here on the FEM Trunk).

The scene of :func:`pliant.robots.trunk_cube.trunk_cube`: the Trunk lying along +z under
gravity -y, its base on a carriage translating along z, a rigid cube on the floor beside its
distal half (+x side).

Observation (thesis: "16 points on the skeleton + cube centre + goal"): ``n_points`` points
along the neutral fibre, the cube's centre and the goal's (x, z), divided by the trunk's length
(16 x 3 + 3 + 2 = 53 values, the authors' code's). Action: continuous (thesis), Box(9) in
[-1, 1]: the 8 cables (targets in [0, max], ``"absolute"``, or increments, ``"increment"``, as
:class:`pliant.envs.trunk.TrunkEnv`) and the carriage's target in [base_low, base_high] mm,
reached at most at ``base_speed`` mm/s; discrete: 18 actions, one cable pulled or released by
``action_scale`` mm (16) or the carriage moved by -``base_step`` / +``base_step`` mm.
``planar=True`` drives only the four cables that bend the trunk towards -x and +x (in the
floor's plane, where the cube moves; the others stay slack): Box(5) or Discrete(10), the FEM's
form of :class:`pliant.envs.trunk_push_proxy.TrunkPushProxyEnv`'s ``planar``. (The
thesis' proxy acts on two beams' bendings instead of cables: the FEM Trunk's actuators are its
cables.) Reward: thesis, -d / L - ``contact_weight`` x d_c / L with d the cube-goal distance in
the floor's plane (x, z), d_c the distance from the cube's centre to the nearest fibre point
(the thesis' negative weighted trunk-cube distance, favouring contact) and L the trunk's
length; ``reward="sofagym"`` (authors' code): -d / L alone. Terminated (solved) when d <
``goal_tolerance`` = 8 mm (5 % of the trunk's length, thesis). The goal is the cube's start
plus an offset drawn in [goal_low, goal_high] (x, z). 10 steps of 30 x 0.01 s (0.3 s a step,
the thesis' iteration). The trunk starts settled under gravity.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pliant.envs.actions import ActionMap, RampTarget, scaled_box
from pliant.envs.base import floor_goal
from pliant.envs.config import SimulationConfig, check_interval, check_positive, taken
from pliant.envs.trunk import LENGTH, TrunkEnv
from pliant.model import Model
from pliant.robots.trunk_cube import trunk_cube


@dataclass(frozen=True)
class CubePush:
    """The cube-pushing task's settings, the same for the FEM Trunk and its proxy: the reward's
    contact weight, the base's range (mm, 0 inside it), speed (mm/s) and discrete step (mm),
    the goal's offset range (x, z) from the cube's start and tolerance (mm), the observed
    points, whether the action drives the trunk in the floor's plane only, and the steps it
    settles under gravity. Given as keywords of either environment."""

    contact_weight: float = 0.2
    base_low: float = -40.0
    base_high: float = 40.0
    base_speed: float = 100.0
    base_step: float = 5.0
    goal_low: tuple[float, float] = (5.0, -30.0)
    goal_high: tuple[float, float] = (40.0, 20.0)
    goal_tolerance: float = 8.0
    n_points: int = 16
    planar: bool = False
    settle_steps: int = 30

    def __post_init__(self) -> None:
        check_interval("base", self.base_low, self.base_high, contains=0.0)
        check_positive("base_speed", self.base_speed)
        check_positive("base_step", self.base_step)


class CubePushTask:
    """The cube-pushing task shared by the FEM Trunk and its proxy: the cube (the model's first
    rigid body), a goal on the floor drawn relative to it, the distance in the x-z plane, and
    the reward: -d / length, plus (``contact=True``) -w d_contact / length, d_contact the
    distance from the cube to the nearest observed trunk point (favours contact, §4.1.2).
    Hosts define ``contact_distance()`` and take their settings with :meth:`_take_push`."""

    def _take_push(self, kwargs: dict) -> CubePush:
        """The :class:`CubePush` settings taken out of the constructor's keywords, and kept."""
        push = self.push = CubePush(**taken(CubePush, kwargs))
        self.contact_weight = float(push.contact_weight)
        self.base_low, self.base_high = float(push.base_low), float(push.base_high)
        self.base_speed, self.base_step = float(push.base_speed), float(push.base_step)
        self.planar = bool(push.planar)
        return push

    def cube(self) -> np.ndarray:
        return self.state.rigid_positions[0]

    def distance(self) -> float:
        gap = self.cube() - self.task["goal"]
        return float(np.hypot(gap[0], gap[2]))

    def _draw_goal(self, rng, options) -> None:
        self.task["goal"] = floor_goal(rng, options, self.cube(), self.goal_low, self.goal_high)
        self.task["distance"] = self.distance()

    def _push_reward(self, length: float, contact: bool):
        d = self.distance()
        self.task["distance"] = d
        parts = {"goal": -d / length}
        if contact:
            parts["contact"] = -self.contact_weight * self.contact_distance() / length
        return sum(parts.values()), d < self.goal_tolerance, parts

    def _render_goal(self):
        return self.task["goal"]


class TrunkPushEnv(CubePushTask, TrunkEnv):
    name = "TrunkPush"
    view = (60.0, -60.0)
    default_config = SimulationConfig(substeps=30, action_type="continuous")
    robot_defaults = {"mesh_size": 8.0}

    def __init__(self, *, action_scale: float = 5.0, **kwargs) -> None:
        """Keywords: ``action_scale`` (mm), those of :class:`CubePush` and of
        :class:`pliant.envs.trunk.TrunkEnv`."""
        push = self._take_push(kwargs)
        super().__init__(
            action_scale=action_scale,
            goal_low=push.goal_low,
            goal_high=push.goal_high,
            goal_tolerance=push.goal_tolerance,
            n_points=push.n_points,
            settle_steps=push.settle_steps,
            **kwargs,
        )
        self.observation_space = scaled_box(-3.0, 3.0, (3 * self.n_points + 5,))

    def _scene_model(self) -> Model:
        self.carriage = self.ramp("carriage", 0.0)
        model = trunk_cube(base_motion=self.carriage.scalar, **self.robot_kwargs)
        # The cables an action drives (the others stay slack): those pulling towards -x and +x
        # (1, 3 long; 5, 7 short) when planar, else all eight.
        self.driven = np.array([1, 3, 5, 7]) if self.planar else np.arange(len(model.actuators))
        return model

    def cable_actions(self) -> ActionMap:
        """The driven cables, then the carriage: discrete, moved by -/+ ``base_step`` mm;
        continuous, its target in [base_low, base_high], at most ``base_speed`` mm/s."""
        steps = [[-self.base_step], [self.base_step]]
        carriage = RampTarget(
            "carriage",
            self.base_low,
            self.base_high,
            steps=steps,
            continuous="interval",
            speed=self.base_speed,
            memory="base",
        )
        return self.cables(self.driven) + carriage

    def contact_distance(self) -> float:
        points = self.fibre.positions(self.state.positions)
        return float(np.linalg.norm(points - self.cube(), axis=1).min())

    def _reset_task(self, rng, options) -> None:
        self._draw_goal(rng, options)
        self.task["base"] = 0.0

    def _observe(self) -> np.ndarray:
        return self.fibre_observation(self.cube(), self.task["goal"][[0, 2]])

    def _reward(self):
        return self._push_reward(LENGTH, contact=self.reward_variant == "thesis")
