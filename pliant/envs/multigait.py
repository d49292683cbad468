"""Multigait locomotion with the full FEM model (thesis §3.1.2, §3.4.1; SofaGym
multigaitrobot-v0, which runs the reduced model: see the reduction package for that one).

Observation: ``n_points`` points spread uniformly over the body (farthest-point sampling of the
surface nodes at rest), relative to the body's rest centre, divided by its length. Action:
discrete (SofaGym's 6): inflate or deflate the centre, the front pair or the rear pair (all or
nothing: the group's chambers move to their ``amplitude`` or to 0 over the step);
continuous: Box(5) in [-1, 1], each chamber's command (volume growth) in [0, amplitude]
(``symmetric=True``: Box(3), the rear pair, the centre, the front pair). Reward: the forward
displacement of the centre of mass over the step (thesis: x_t - x_{t-1}); SofaGym's
``reward="sofagym"`` clips it at 0 (max(0, dx), what Table 3.2's cumulative rewards sum).
Forward is -x in the builder's frame (away from the legs inflated first in the hand gait).
6 steps of 60 x 0.01 s (0.6 s a step).
"""

from __future__ import annotations

import numpy as np

from pliant.envs.actions import ActionMap, scaled_box
from pliant.envs.base import SoftRobotEnv
from pliant.envs.config import SimulationConfig
from pliant.mesh.multigait import CHAMBERS
from pliant.model import Model
from pliant.robots.multigait import centre_of_mass, multigait

#: action groups of the discrete and symmetric actions (SofaGym's order: centre, front, rear).
GROUPS = (("centre",), ("front_left", "front_right"), ("rear_left", "rear_right"))
FORWARD = np.array([-1.0, 0.0, 0.0])


class ChamberGroups(ActionMap):
    """The chambers' commands (in CHAMBERS order) by groups (:data:`GROUPS`): discrete, group
    g inflated to its `amplitude` (action 2g) or deflated to 0 (2g + 1), all or nothing;
    continuous, each group's command (``symmetric``) or each chamber's, 0.5 (a + 1) x
    amplitude."""

    def __init__(self, amplitude: np.ndarray, symmetric: bool) -> None:
        self.amplitude = amplitude
        self.symmetric = symmetric
        self.groups = [np.array([CHAMBERS.index(c) for c in g]) for g in GROUPS]
        self.n_discrete = 2 * len(GROUPS)
        self.n_continuous = len(GROUPS) if symmetric else len(CHAMBERS)

    def discrete(self, env, action, commands):
        target = commands.actuators.copy()
        group = self.groups[action // 2]
        target[group] = self.amplitude[group] if action % 2 == 0 else 0.0
        return commands.with_actuators(target)

    def continuous(self, env, action, commands):
        if not self.symmetric:
            return commands.with_actuators(0.5 * (np.asarray(action) + 1.0) * self.amplitude)
        target = commands.actuators.copy()
        for g, a in zip(self.groups, action, strict=True):
            target[g] = 0.5 * (a + 1.0) * self.amplitude[g]
        return commands.with_actuators(target)


def farthest_points(points: np.ndarray, k: int) -> np.ndarray:
    """Indices of k points spread over `points` by greedy farthest-point sampling (from the
    point nearest the centroid: deterministic)."""
    chosen = [int(np.argmin(np.linalg.norm(points - points.mean(axis=0), axis=1)))]
    gap = np.linalg.norm(points - points[chosen[0]], axis=1)
    for _ in range(k - 1):
        chosen.append(int(np.argmax(gap)))
        gap = np.minimum(gap, np.linalg.norm(points - points[chosen[-1]], axis=1))
    return np.array(chosen)


class MultigaitEnv(SoftRobotEnv):
    name = "Multigait"
    view = (35.0, -60.0)
    default_config = SimulationConfig(substeps=60)
    robot_defaults = {"mesh_size": 6.0}
    rewards = ("thesis", "sofagym")

    def __init__(
        self,
        *,
        symmetric: bool = True,
        amplitude: tuple[float, float] = (4900.0, 3300.0),
        n_points: int = 20,
        **kwargs,
    ) -> None:
        self.symmetric = bool(symmetric)
        self.n_points = int(n_points)
        centre, leg = amplitude
        self.amplitude = np.array([centre if c == "centre" else leg for c in CHAMBERS])
        super().__init__(**kwargs)
        self.use_actions(ChamberGroups(self.amplitude, self.symmetric))
        self.observation_space = scaled_box(-3.0, 3.0, (3 * self.n_points,))

    def _build(self) -> Model:
        model = multigait(**self.robot_kwargs)
        rest = model.body.rest_positions
        surface = np.unique(model.body.mesh.boundary_triangles())
        self.points = surface[farthest_points(rest[surface], self.n_points)]
        self.centre0 = rest.mean(axis=0)
        self.length = float(np.ptp(rest[:, 0]))
        return model

    def progress(self) -> float:
        """Forward position of the centre of mass (mm)."""
        return float(centre_of_mass(self.model, self.state.positions) @ FORWARD)

    def _reset_task(self, rng, options) -> None:
        self.task["x"] = self.progress()
        self.task["x0"] = self.task["x"]

    def _observe(self) -> np.ndarray:
        return ((self.state.positions[self.points] - self.centre0) / self.length).ravel()

    def _reward(self):
        x = self.progress()
        dx = x - self.task["x"]
        self.task["x"] = x
        r = dx if self.reward_variant == "thesis" else max(0.0, dx)
        return r, False, {"forward": r}

    def _info(self):
        return {"travelled": self.task["x"] - self.task["x0"]}
