"""The Trunk on a translating base pushing a cube to a goal, on its beam-skeleton proxy
(thesis §4.1.2, C.5): the task of :class:`pliant.envs.trunk_push.TrunkPushEnv` with the proxy
of :func:`pliant.proxy.trunk_proxy` (calibrated on the FEM Trunk) in place of the FEM body.

Observation (thesis: 16 points on the skeleton + cube centre + goal): 16 skeleton nodes spread
along it, the cube's centre and the goal's (x, z), divided by the trunk's length (53 values).
Action: continuous (thesis), Box(5) in [-1, 1]: the two bendings of each beam, targets
reached linearly over the step, and the base's target in [base_low, base_high] mm, at most
``base_speed`` mm/s; discrete: 10 actions, one bending moved by +-``bend_step`` or the base by
+-``base_step`` mm. The bendings' commands stay within +-``bend_limit`` (an action of 1 is a
command of ``bend_limit``): the thesis' a priori amplitude limit (§4.1.1), 1 by default (the
calibrated maximum curvatures), where a command of 0.1 already pushes the cube 20 mm and
larger ones sweep it away. ``planar=True``, another a priori restriction (§4.1.1: the action
space reduced to what the task needs): the beams bend only towards +-x, in the floor's plane
where the cube moves (their bendings towards +-y, up and down, held at 0); the action is then
Box(3) (lower, upper bending towards +x, base) or Discrete(6). ``actions="cables"``
(continuous only): the FEM Trunk's action space on the proxy, Box(9) as
:class:`pliant.envs.trunk_push.TrunkPushEnv`'s (8 absolute cable targets within ``bend_limit``
of the courses, 70 and 40 mm, then the base), mapped to the bendings by the calibration's
cables -> bendings map (:func:`pliant.proxy.references.trunk_commands`): the same proxy, the
FEM's parametrisation of its actuation (opposite cables pulled together cancel, or, on a
proxy with axial commands, ``lower_cocontraction``/``upper_cocontraction``, shorten it).
Reward (thesis): -d / L - ``contact_weight`` d_c / L, d the cube-goal distance in the floor's
plane, d_c the distance from the cube's centre to the nearest skeleton node; terminated when
d < ``goal_tolerance`` (8 mm). Goal: the cube's start plus an offset in [goal_low, goal_high]
(x, z). 10 steps of 30 x 0.01 s (0.3 s a step). The proxy starts settled under gravity.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np

from pliant.envs.actions import Commands, scaled_box
from pliant.envs.base import SoftRobotEnv
from pliant.envs.config import (
    EnvConfigError,
    SimulationConfig,
    check_choice,
)
from pliant.envs.trunk_push import CubePushTask
from pliant.model import Model, State
from pliant.proxy import trunk_proxy
from pliant.proxy.actuation import ProxySolver
from pliant.proxy.references import trunk_commands
from pliant.robots.common import settled

#: The FEM Trunk's cable courses (mm): four long cables, then four short ones (SoftRobots').
CABLE_COURSES = np.array([70.0] * 4 + [40.0] * 4)


class TrunkPushProxyEnv(CubePushTask, SoftRobotEnv):
    name = "TrunkPushProxy"
    view = (60.0, -60.0)

    default_config = SimulationConfig(substeps=30, action_type="continuous")

    def __init__(
        self,
        *,
        bend_step: float = 0.25,
        bend_limit: float = 1.0,
        actions: str = "bendings",
        **kwargs,
    ) -> None:
        """Keywords: those above, those of :class:`pliant.envs.trunk_push.CubePush`, and the
        proxy builder's."""
        push = self._take_push(kwargs)
        if not 0.0 < bend_limit <= 1.0:
            raise EnvConfigError(f"bend_limit must lie in (0, 1], got {bend_limit!r}")
        check_choice("actions", actions, ("bendings", "cables"))
        self.actions = actions
        self.bend_limit = float(bend_limit)
        self.bend_step = float(bend_step)
        self.goal_low, self.goal_high = np.asarray(push.goal_low), np.asarray(push.goal_high)
        self.goal_tolerance = float(push.goal_tolerance)
        self.n_points = int(push.n_points)
        self.settle_steps = int(push.settle_steps)
        super().__init__(**kwargs)
        if actions == "cables" and (self.action_type != "continuous" or self.planar):
            raise EnvConfigError("actions='cables' is continuous and drives all eight cables")
        self.sim = ProxySolver(self.proxy, self.sim)
        self.n_actuators = self.proxy.n_controls
        # a proxy with axial commands (cocontraction): only the cables say how much to pull
        self.axial = any(n.endswith("_axial") for n in self.proxy.actuation.names)
        if self.axial and actions != "cables":
            raise EnvConfigError(
                "a proxy with axial commands (cocontraction) takes actions='cables'"
            )
        self.commands = np.zeros(self.n_actuators)
        # The commands an action drives (the rest stay 0): lower_d2, upper_d2 (towards +x) and
        # the base when planar, else all five.
        self.driven = np.array([1, 3, 4]) if self.planar else np.arange(self.n_actuators)
        if self.action_type == "discrete":
            self.action_space = gym.spaces.Discrete(2 * len(self.driven))
        elif actions == "cables":
            self.action_space = scaled_box(-1.0, 1.0, (len(CABLE_COURSES) + 1,))
        else:
            self.action_space = scaled_box(-1.0, 1.0, (len(self.driven),))
        self.observation_space = scaled_box(-3.0, 3.0, (3 * self.n_points + 5,))

    def _build(self) -> Model:
        self.proxy = trunk_proxy(base_limits=(self.base_low, self.base_high), **self.robot_kwargs)
        rod = self.proxy.rod
        self.length = float(rod.lengths.sum())
        self.nodes = np.unique(np.linspace(0, rod.n_centreline - 1, self.n_points).round())
        self.nodes = self.nodes.astype(np.int64)
        return self.proxy.model

    def _initial_state(self) -> State:
        return settled(self.model, self.sim, self.settle_steps)

    def contact_distance(self) -> float:
        x = self.proxy.skeleton(self.state.positions)
        return float(np.linalg.norm(x - self.cube(), axis=1).min())

    def _reset_task(self, rng, options) -> None:
        self._draw_goal(rng, options)

    def _commands(self, action) -> Commands:
        """The bendings (or the cables mapped onto them) and the base, the last command, at
        most ``base_speed`` mm/s."""
        if self.action_type == "discrete":
            target = self.commands.copy()
            i, sign = self.driven[action // 2], 1.0 if action % 2 == 0 else -1.0
            step = self.base_step if i == self.n_actuators - 1 else self.bend_step
            bend = target[:-1] + (np.arange(4) == i) * sign * step
            target[:-1] = np.clip(bend, -self.bend_limit, self.bend_limit)
            base = target[-1] + (sign * step if i == self.n_actuators - 1 else 0.0)
            base = float(np.clip(base, self.base_low, self.base_high))
        elif self.actions == "cables":
            cables = 0.5 * (action[:-1] + 1.0) * CABLE_COURSES * self.bend_limit
            target = trunk_commands(cables, self.axial)
            s = 0.5 * (action[-1] + 1.0)
            base = self.base_low + s * (self.base_high - self.base_low)
        else:
            target = np.zeros(self.n_actuators)
            target[self.driven] = action
            target[:-1] *= self.bend_limit
            s = 0.5 * (target[-1] + 1.0)
            base = self.base_low + s * (self.base_high - self.base_low)
        now = self.commands[-1]
        reach = self.base_speed * self.step_time
        target[-1] = now + np.clip(base - now, -reach, reach)
        return Commands(target)

    def _observe(self) -> np.ndarray:
        x = self.proxy.skeleton(self.state.positions)[self.nodes]
        goal = self.task["goal"][[0, 2]]
        return np.concatenate([x.ravel(), self.cube(), goal]) / self.length

    def _reward(self):
        return self._push_reward(self.length, contact=True)
