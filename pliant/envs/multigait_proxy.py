"""Multigait locomotion on its beam-skeleton proxy (thesis §4.1.2, C.5): the task of
:class:`pliant.envs.multigait.MultigaitEnv` with the proxy of
:func:`pliant.proxy.multigait_proxy` in place of the FEM body.

Observation (thesis): 20 points spread uniformly on the skeleton (farthest-point sampling of its
nodes and element middles at rest), relative to its rest centre, divided by its length;
``observe_commands=True`` (a departure) appends the chambers' commands in [0, 1], which the
points show only through the small shape changes they cause. Action: the
FEM environment's (by default SofaGym's Discrete(6): the centre, the front pair or the rear
pair bent fully or released, all or nothing and symmetric, as the thesis restricts them);
each chamber's command is its beam's bending in [0, 1]. Reward: the forward displacement of
the skeleton's centre of mass over the step. 0.6 s a step (60 x 0.01 s); 12 steps an episode
(the authors' timer, ``max_episode_steps`` of the registration).
"""

from __future__ import annotations

import numpy as np

from pliant.envs.actions import scaled_box
from pliant.envs.multigait import FORWARD, MultigaitEnv, farthest_points
from pliant.model import Model
from pliant.proxy import multigait_proxy
from pliant.proxy.actuation import ProxySolver


class MultigaitProxyEnv(MultigaitEnv):
    name = "MultigaitProxy"
    robot_defaults = {}

    def __init__(self, *, observe_commands: bool = False, **kwargs) -> None:
        kwargs.setdefault("amplitude", (1.0, 1.0))
        self.observe_commands = bool(observe_commands)
        super().__init__(**kwargs)
        self.sim = ProxySolver(self.proxy, self.sim)
        self.n_actuators = self.proxy.n_controls
        self.commands = np.zeros(self.n_actuators)
        if self.observe_commands:
            self.observation_space = scaled_box(-3.0, 3.0, (3 * self.n_points + self.n_actuators,))

    def _build(self) -> Model:
        self.robot_kwargs.pop("mesh_size", None)
        self.proxy = multigait_proxy(**self.robot_kwargs)
        rod = self.proxy.rod
        rest = rod.centreline(rod.rest_positions)
        pairs = np.vstack([np.column_stack([np.arange(len(rest))] * 2), rod.elements])
        candidates = 0.5 * (rest[pairs[:, 0]] + rest[pairs[:, 1]])
        self.point_pairs = pairs[farthest_points(candidates, self.n_points)]
        self.centre0 = rest.mean(axis=0)
        self.length = float(np.ptp(rest[:, 0]))
        self._masses = rod.node_masses[: rod.n_centreline]
        return self.proxy.model

    def _skeleton(self) -> np.ndarray:
        return self.proxy.skeleton(self.state.positions)

    def progress(self) -> float:
        """Forward position of the skeleton's centre of mass (mm)."""
        x = self._skeleton()
        return float(self._masses @ x / self._masses.sum() @ FORWARD)

    def _observe(self) -> np.ndarray:
        x = self._skeleton()
        points = 0.5 * (x[self.point_pairs[:, 0]] + x[self.point_pairs[:, 1]])
        obs = ((points - self.centre0) / self.length).ravel()
        if self.observe_commands:
            obs = np.concatenate([obs, self.commands])
        return obs
