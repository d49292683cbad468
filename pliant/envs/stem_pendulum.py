"""StemPendulum: swing a stem up by a torque at its pivot (SofaGym stempendulum-v0; not in the
thesis).

The scene of :func:`pliant.robots.stem_pendulum.stem_pendulum`: a stiff rod hanging from a
hinge, a bounded torque motor on the hinge (a fifth of the torque that holds the stem
horizontal: swinging it up takes several swings). The episode starts hanging at rest.

Observation (5 values, SofaGym's size): the tip's (x, z) from the pivot divided by the length
L, its velocity (x, z) divided by ``velocity_scale`` mm/s and the motor's torque divided by its
maximum. Action: Box(1) in [-1, 1] (SofaGym's), the torque a x max about +y (ramped over the
sub-steps; a positive torque moves the hanging tip towards -x); ``action_type="discrete"``: 3
actions, -max, 0, +max. Reward (SofaGym's): -dist / (2 L), dist the distance from the tip to
the upright position (0, 0, L), in [-1, 0].
Not terminated; 50 steps of 10 x 0.01 s.
"""

from __future__ import annotations

import numpy as np

from pliant.envs.actions import ActionMap, scaled_box
from pliant.envs.base import SoftRobotEnv
from pliant.envs.config import SimulationConfig
from pliant.model import Model
from pliant.robots.stem_pendulum import stem_pendulum


class Torque(ActionMap):
    """The first actuator's command a x `high`: discrete, a = -1, 0 or +1; continuous, a in
    [-1, 1] (the other actuators hold)."""

    n_discrete = 3
    n_continuous = 1

    def __init__(self, high: float) -> None:
        self.high = high

    def discrete(self, env, action, commands):
        return self._set(float(action - 1), commands)

    def continuous(self, env, action, commands):
        return self._set(float(action[0]), commands)

    def _set(self, a: float, commands):
        target = commands.actuators.copy()
        target[0] = a * self.high
        return commands.with_actuators(target)


class StemPendulumEnv(SoftRobotEnv):
    name = "StemPendulum"
    view = (5.0, -90.0)
    default_config = SimulationConfig(substeps=10, action_type="continuous")
    robot_defaults = {"length": 100.0}

    def __init__(self, *, velocity_scale: float = 1000.0, **kwargs) -> None:
        self.velocity_scale = float(velocity_scale)
        super().__init__(**kwargs)
        self.length = float(self.robot_kwargs["length"])
        self.max_torque = float(self.model.actuators[0].max_force)
        self.use_actions(Torque(self.max_torque))
        self.observation_space = scaled_box(-10.0, 10.0, (5,))

    def _build(self) -> Model:
        return stem_pendulum(**self.robot_kwargs)

    def _reset_task(self, rng, options) -> None:
        self.task["goal"] = np.array([0.0, 0.0, self.length])

    def _tip(self, x: np.ndarray) -> np.ndarray:
        return self.model.effectors[0].points.positions(x)[0]

    def distance(self) -> float:
        return float(np.linalg.norm(self._tip(self.state.positions) - self.task["goal"]))

    def _observe(self) -> np.ndarray:
        tip = self._tip(self.state.positions)
        velocity = self._tip(self.state.velocities)
        return np.array(
            [
                tip[0] / self.length,
                tip[2] / self.length,
                velocity[0] / self.velocity_scale,
                velocity[2] / self.velocity_scale,
                self.commands[0] / self.max_torque,
            ]
        )

    def _reward(self):
        r = -self.distance() / (2.0 * self.length)
        return r, False, {"distance": r}

    def _info(self):
        return {"distance": self.distance()}
