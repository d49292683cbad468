"""Trunk reaching (thesis §3.1.2, Eq. 3.2; SofaGym trunk-v0).

Observation: ``n_points`` points along the neutral fibre (the axis, base to tip) and the goal,
in mm divided by the trunk's length (21 points + goal = 66 values, SofaGym's). Action:
discrete, one of the 8 cables pulled or released by ``action_scale`` mm (16 actions,
SofaGym's); continuous, the 8 cable displacements as targets in [0, max] (``"absolute"``) or
increments of at most ``action_scale`` (``"increment"``). Reward: Eq. 3.2 on the tip's
distance to the goal (``reward="thesis"``), or SofaGym's min(sqrt(max((d_prev - d)/d_prev,
0)), 1) (``"sofagym"``). Terminated when the tip is within ``goal_tolerance`` mm (SofaGym: 1).
250 steps of 5 x 0.01 s (TimeLimit). The trunk starts settled under gravity.
"""

from __future__ import annotations

import numpy as np

from pliant.constraints.base import EmbeddedPoints
from pliant.envs.actions import scaled_box
from pliant.envs.config import EnvConfigError
from pliant.envs.reaching import CableReachingEnv
from pliant.model import Model, State
from pliant.robots.common import settled
from pliant.robots.trunk import trunk

LENGTH = 195.0


def neutral_fibre(model: Model, n_points: int) -> EmbeddedPoints:
    """`n_points` points along the Trunk's axis (x = y = 0, z from 0 to its length), embedded
    in its mesh: the neutral fibre the observations read."""
    z = np.linspace(0.0, LENGTH, n_points)
    axis = np.column_stack([np.zeros(n_points), np.zeros(n_points), z])
    return EmbeddedPoints(model.body.mesh, axis)


class TrunkEnv(CableReachingEnv):
    name = "Trunk"
    view = (20.0, -60.0)
    robot_defaults = {"mesh_size": 5.2}
    #: the builder of the scene (the Trunk alone, or with an object: a cup, a cube)
    builder = staticmethod(trunk)

    def __init__(
        self,
        *,
        goal_low: tuple[float, ...] = (-60.0, -60.0, 130.0),
        goal_high: tuple[float, ...] = (60.0, 60.0, 190.0),
        goal_tolerance: float = 1.0,
        n_points: int = 21,
        settle_steps: int = 50,
        **kwargs,
    ) -> None:
        if n_points < 2:
            raise EnvConfigError(f"n_points must be >= 2, got {n_points}")
        self.n_points = int(n_points)
        self.settle_steps = int(settle_steps)
        super().__init__(
            goal_low=goal_low, goal_high=goal_high, goal_tolerance=goal_tolerance, **kwargs
        )
        self.observation_space = scaled_box(-3.0, 3.0, (3 * (self.n_points + 1),))

    def _build(self) -> Model:
        model = self._scene_model()
        self.fibre = neutral_fibre(model, self.n_points)
        return model

    def _scene_model(self) -> Model:
        """The model of the scene, before the environment reads its fibre."""
        return self.builder(**self.robot_kwargs)

    def _initial_state(self) -> State:
        return settled(self.model, self.sim, self.settle_steps)

    def tip(self) -> np.ndarray:
        return self.model.effectors[0].position(self.state.positions)[0]

    def effector_position(self) -> np.ndarray:
        return self.tip()

    def sofagym_progress(self, distance: float) -> float:
        """min(sqrt(max((d_prev - d) / d_prev, 0)), 1)."""
        previous = self.task["distance"]
        return min(np.sqrt(max((previous - distance) / previous, 0.0)), 1.0) if previous else 0.0

    def fibre_observation(self, *points) -> np.ndarray:
        """The neutral fibre's points, then `points` (flattened), divided by the length."""
        fibre = self.fibre.positions(self.state.positions).ravel()
        return np.concatenate([fibre, *(np.ravel(p) for p in points)]) / LENGTH

    def _observe(self) -> np.ndarray:
        return self.fibre_observation(self.task["goal"])
