"""A toy world with a known partition, for the tests and quick demos: a point on a segment
split into three regions (left, middle, right: the shape of CartStemContact's graph), starting
in the left region with its goal in the right one, so that solving the task changes region.

Observation [x, x_goal]; action a ∈ [-1, 1] moves x by ``step·a`` (clipped to [-1, 1]);
reward −|x − x_goal| per step; terminated when |x − x_goal| < ``tolerance``.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np

from pliant.learn.graph.graph import ConfigurationGraph

BOUNDS = (-1.0 / 3.0, 1.0 / 3.0)


def corridor_partition(obs: np.ndarray) -> int:
    """Region of x: 0 left of −1/3, 2 right of 1/3, 1 between."""
    x = float(obs[0])
    return 0 if x < BOUNDS[0] else (2 if x > BOUNDS[1] else 1)


def corridor_graph(partition=corridor_partition) -> ConfigurationGraph:
    return ConfigurationGraph(
        ["left", "middle", "right"], [[0, 1], [0, 1, 2], [1, 2]], partition=partition, start=0
    )


class CorridorEnv(gym.Env):
    def __init__(self, step: float = 0.1, tolerance: float = 0.05, max_steps: int = 40) -> None:
        self.step_size, self.tolerance, self.max_steps = step, tolerance, max_steps
        self.observation_space = gym.spaces.Box(-1.0, 1.0, (2,), np.float32)
        self.action_space = gym.spaces.Box(-1.0, 1.0, (1,), np.float32)

    def _obs(self) -> np.ndarray:
        return np.array([self.x, self.goal], dtype=np.float32)

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        self.x = self.np_random.uniform(-0.9, -0.6)
        self.goal = self.np_random.uniform(0.5, 0.9)
        self.t = 0
        return self._obs(), {}

    def step(self, action):
        self.x = float(np.clip(self.x + self.step_size * np.clip(action[0], -1, 1), -1, 1))
        self.t += 1
        distance = abs(self.x - self.goal)
        terminated = distance < self.tolerance
        info = {"is_success": terminated}
        return self._obs(), -distance, terminated, self.t >= self.max_steps, info


def corridor_controller(step: float = 0.1):
    """The convex-optimisation internal agent of the corridor: argmin_{|a| ≤ 1} (x + step·a −
    x_goal)², in closed form a = clip((x_goal − x)/step, −1, 1)."""
    return lambda obs: np.clip([(obs[1] - obs[0]) / step], -1.0, 1.0)
