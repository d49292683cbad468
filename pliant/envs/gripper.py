"""Gripper: grasp a cube and lift it to a goal height (thesis §3.1.2, §3.2.1; SofaGym
gripper-v0).

Two cable fingers hang from a base that translates along any axis (:mod:`pliant.robots.gripper`);
one command pulls both cables (SofaGym's single cable value). A rigid cube stands on the floor
between the fingers, at a random (x, y) offset of at most ``cube_range`` mm; the goal is a
height ``U(goal_low, goal_high)`` mm above the cube's start.

Observation (thesis: "object and goal positions, the displacement of the cable, the tips of the
fingers", normalised by their extreme values): the cube's centre, the goal, the cable command
divided by its maximum and the two fingertips, lengths divided by ``length_scale`` (13 values);
``observation="sofagym"``: the cube's 8 corners, the cable, the fingertips' midpoint and the
goal (31 values, SofaGym's). Action: discrete (SofaGym's 8): base -x, +x, -y, +y, up by 2 x
``action_scale``, down by ``action_scale``, cable +1 / -1 (``action_scale`` mm); continuous:
Box(4) in [-1, 1], the base's increments (x, y, z) of at most ``action_scale`` (2 x upwards)
and the cable's of at most ``action_scale``. The base stays in ``base_low``..``base_high``
(offsets from its start), the cable in [0, its maximum].

Reward: thesis -|z_cube - z_goal| / ``length_scale`` (Eq. of §3.1.2, printed without its minus
sign: the distance is what the agent reduces); ``reward="sofagym"``: the decrease of
|z_cube - z_goal| over the step divided by 20, clipped to [0, 1], plus 1 on success. Terminated
when |z_cube - z_goal| <= ``goal_tolerance`` (3 mm, SofaGym's). 250 steps of 5 x 0.01 s.

``cube_push_down`` (thesis §3.2.1): each step a downward force of random magnitude in
[0, ``push_force``] (mN) pulls the cube, to reward firm grasps. Pliant's rigid bodies take no
external force, so it is applied as the impulse F x step time it gives over the step, added to
the cube's velocity at the step's start.

:func:`expert_action` is the thesis' hand-designed strategy (Fig. 3.8) for behaviour cloning.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np

from pliant.envs.actions import ActuatorTargets, RampTarget, scaled_box
from pliant.envs.base import SoftRobotEnv
from pliant.envs.config import check_interval, check_positive
from pliant.model import Model
from pliant.robots.gripper import soft_gripper

# Discrete actions of the base, in units of action_scale: -x, +x, -y, +y, up 2, down 1 (the
# cable's +1 and -1 follow them).
_MOVES = np.array(
    [
        [-1.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, -1.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 2.0],
        [0.0, 0.0, -1.0],
    ]
)
_CORNERS = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], float)


class BaseIncrement(RampTarget):
    """The gripper's base moved by increments of at most ``scale`` on each axis, twice that
    upwards."""

    def increment(self, action: np.ndarray) -> np.ndarray:
        move = super().increment(action)
        move[2] *= 2.0 if move[2] > 0 else 1.0
        return move


class GripperEnv(SoftRobotEnv):
    name = "Gripper"
    view = (15.0, -70.0)
    robot_defaults = {"mesh_size": 5.0}
    rewards = observations = ("thesis", "sofagym")

    def __init__(
        self,
        *,
        action_scale: float = 1.0,
        base_low: tuple[float, float, float] = (-15.0, -15.0, -5.0),
        base_high: tuple[float, float, float] = (15.0, 15.0, 40.0),
        cube_range: float = 5.0,
        goal_low: float = 10.0,
        goal_high: float = 30.0,
        goal_tolerance: float = 3.0,
        cube_push_down: bool = False,
        push_force: float = 50.0,
        length_scale: float = 50.0,
        **kwargs,
    ) -> None:
        self.action_scale = check_positive("action_scale", action_scale)
        check_interval("goal", goal_low, goal_high, floor=0.0, strict=False)
        self.base_low = np.asarray(base_low, dtype=float)
        self.base_high = np.asarray(base_high, dtype=float)
        self.cube_range = float(cube_range)
        self.goal_low, self.goal_high = float(goal_low), float(goal_high)
        self.goal_tolerance = float(goal_tolerance)
        self.cube_push_down = bool(cube_push_down)
        self.push_force = float(push_force)
        self.length_scale = float(length_scale)
        super().__init__(**kwargs)
        self.max_cable = float(self.model.actuators[0].max_displacement)
        self.cube_half = float(self.model.rigid_bodies[0].shape.half_extents[0])
        self.cube_mass = float(self.model.rigid_bodies[0].mass)
        # The fingers' inner faces: the smallest |x| of the nodes of the fingers' lower halves.
        rest = self.model.body.rest_positions
        fingers = rest[:, 2] < 0.5 * rest[self.model.body.fixed_nodes, 2].min()
        room = float(np.abs(rest[fingers, 0]).min()) - self.cube_half
        if not 0 <= self.cube_range < room:
            raise ValueError(
                f"cube_range must lie in [0, {room:g}) mm (the cube between the fingers), got"
                f" {cube_range!r}"
            )
        steps = self.action_scale * _MOVES
        base = BaseIncrement(
            "base",
            self.base_low,
            self.base_high,
            steps=steps,
            continuous="increment",
            scale=self.action_scale,
            memory="target",
            size=3,
        )
        cable = ActuatorTargets(
            [self.max_cable],
            step=self.action_scale,
            mode="increment",
            scale=self.action_scale,
            shared=True,
        )
        self.use_actions(base + cable)
        n_obs = 13 if self.observation_variant == "thesis" else 31
        self.observation_space = scaled_box(-5.0, 5.0, (n_obs,))

    def _build(self) -> Model:
        self.base = self.ramp("base", [0.0, 0.0, 0.0])
        return soft_gripper(base_motion=self.base.value, **self.robot_kwargs)

    def _reset_task(self, rng, options) -> None:
        options = options or {}
        offset = options.get("cube")
        if offset is None:
            offset = rng.uniform(-self.cube_range, self.cube_range, 2)
        self.state.rigid_positions[0, :2] += np.asarray(offset, dtype=float).reshape(2)
        height = options.get("goal")
        if height is None:
            height = rng.uniform(self.goal_low, self.goal_high)
        self.task["goal"] = self.state.rigid_positions[0] + [0.0, 0.0, float(height)]
        self.task["target"] = np.zeros(3)
        self.task["error"] = self.height_error()

    def cube(self) -> np.ndarray:
        return self.state.rigid_positions[0]

    def fingertips(self) -> np.ndarray:
        return np.vstack([e.position(self.state.positions)[0] for e in self.model.effectors])

    def height_error(self) -> float:
        return abs(float(self.cube()[2] - self.task["goal"][2]))

    def _before_step(self) -> None:
        if self.cube_push_down:
            force = self.np_random.uniform(0.0, self.push_force)
            self.state.rigid_velocities[0, 2] -= force * self.step_time / self.cube_mass

    def _observe(self) -> np.ndarray:
        tips = self.fingertips()
        cable = [self.commands[0] / self.max_cable]
        s = self.length_scale
        if self.observation_variant == "thesis":
            return np.concatenate([self.cube() / s, self.task["goal"] / s, cable, tips.ravel() / s])
        corners = self.cube() + (self.cube_half * _CORNERS) @ self.state.rigid_rotations[0].T
        return np.concatenate(
            [corners.ravel() / s, cable, tips.mean(axis=0) / s, self.task["goal"] / s]
        )

    def _reward(self):
        error, previous = self.height_error(), self.task["error"]
        self.task["error"] = error
        success = error <= self.goal_tolerance
        if self.reward_variant == "thesis":
            return -error / self.length_scale, success, {"height": -error / self.length_scale}
        progress = float(np.clip((previous - error) / 20.0, 0.0, 1.0))
        bonus = 1.0 if success else 0.0
        return progress + bonus, success, {"progress": progress, "success": bonus}

    def _info(self):
        return {
            "height_error": self.task["error"],
            "is_success": self.task["error"] <= self.goal_tolerance,
        }


def expert_action(env: gym.Env, *, grasp: float | None = None, tolerance: float = 0.5):
    """The thesis' hand-designed grasp (§3.2.1, Fig. 3.8) as a policy of the state, for
    behaviour cloning: (1) centre the base over the cube on x, then (2) on y, with the cable
    released; (3) close the fingers (cable to `grasp` mm, default 60 % of its maximum) while
    holding; (4) lift the cube to the goal's height and hold it there. Returns an action of the
    environment's own action space (discrete or continuous)."""
    g: GripperEnv = env.unwrapped
    base = g.task["target"]
    # The base's start is centred between the fingers: its offset over the cube is the cube's.
    start = g._initial.rigid_positions[0]
    gap = (g.cube() - start)[:2] - base[:2]
    close = g.max_cable * 0.6 if grasp is None else float(grasp)
    cable = g.commands[0]
    lift = g.task["goal"][2] - g.cube()[2]
    if cable < close - 1e-9:
        # Before the grasp: centre on x, then on y, then close (the cube then follows the base).
        if abs(gap[0]) > tolerance:
            axis, amount = 0, gap[0]
        elif abs(gap[1]) > tolerance:
            axis, amount = 1, gap[1]
        else:
            axis, amount = 3, close - cable
    elif abs(lift) > tolerance:
        axis, amount = 2, lift
    else:
        axis, amount = None, 0.0
    if g.action_type == "continuous":
        action = np.zeros(4, dtype=np.float32)
        if axis is not None:
            reach = g.action_scale * (2.0 if axis == 2 and amount > 0 else 1.0)
            action[axis] = np.clip(amount / reach, -1.0, 1.0)
        return action
    if axis is None:
        return 6  # no "stay" among SofaGym's actions: tighten the grip (capped at the maximum)
    return {0: (0, 1), 1: (2, 3), 2: (5, 4), 3: (7, 6)}[axis][int(amount > 0)]


def expert(env: gym.Env):
    """:func:`expert_action` as an expert for behaviour cloning (:mod:`pliant.learn.bc`,
    ``--bc-expert pliant.envs.gripper:expert``): ``act(observation) -> action`` reading `env`."""
    return lambda observation: expert_action(env)


__all__ = ["GripperEnv", "expert", "expert_action"]
