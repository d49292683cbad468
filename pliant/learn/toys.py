"""Trivial, fast environments for the learners' tests (SB3's identity-test idea: a task a
random policy fails and a working learner solves in a few thousand steps).

``pliant-test/PointReach-v0``: a point on [-1, 1]^dim must reach a goal drawn at reset.
Observation [position, goal]; continuous action: a velocity in [-1, 1]^dim times ``speed``
(discrete: 2 dim + 1 actions, +-speed along one axis or stay). Reward: minus the distance
after the step; terminated (success) within ``tolerance``. With ``diverge_probability`` a
step fails like a diverged simulation: last observation, reward 0, truncated,
``info["diverged"]`` set (the robust-training tests). ``get_state``/``set_state`` snapshot it
exactly, like Pliant's environments, so a training run on it resumes exactly.
"""

from __future__ import annotations

import copy
from typing import Literal

import gymnasium as gym
import numpy as np


class PointReachEnv(gym.Env):
    metadata = {"render_modes": ["rgb_array"], "render_fps": 10}

    def __init__(
        self,
        *,
        dim: int = 1,
        speed: float = 0.25,
        tolerance: float = 0.1,
        action_type: Literal["continuous", "discrete"] = "continuous",
        diverge_probability: float = 0.0,
        render_mode: str | None = None,
    ) -> None:
        self.dim = int(dim)
        self.speed = float(speed)
        self.tolerance = float(tolerance)
        self.diverge_probability = float(diverge_probability)
        self.render_mode = render_mode
        self.observation_space = gym.spaces.Box(-1.0, 1.0, (2 * self.dim,), np.float32)
        if action_type == "continuous":
            self.action_space = gym.spaces.Box(-1.0, 1.0, (self.dim,), np.float32)
        else:
            self.action_space = gym.spaces.Discrete(2 * self.dim + 1)
        self.position = np.zeros(self.dim)
        self.goal = np.zeros(self.dim)

    def _obs(self) -> np.ndarray:
        return np.concatenate([self.position, self.goal]).astype(np.float32)

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        self.position = self.np_random.uniform(-1.0, 1.0, self.dim)
        self.goal = self.np_random.uniform(-1.0, 1.0, self.dim)
        return self._obs(), {}

    def step(self, action):
        if self.diverge_probability and self.np_random.random() < self.diverge_probability:
            return self._obs(), 0.0, False, True, {"diverged": "PointReach: injected failure"}
        if isinstance(self.action_space, gym.spaces.Discrete):
            velocity = np.zeros(self.dim)
            a = int(action)
            if a < 2 * self.dim:
                velocity[a // 2] = 1.0 if a % 2 == 0 else -1.0
        else:
            velocity = np.clip(np.asarray(action, dtype=float), -1.0, 1.0)
        self.position = np.clip(self.position + self.speed * velocity, -1.0, 1.0)
        distance = float(np.linalg.norm(self.position - self.goal))
        success = distance < self.tolerance
        return self._obs(), -distance, success, False, {"is_success": success}

    def get_state(self) -> dict:
        return {
            "position": self.position.copy(),
            "goal": self.goal.copy(),
            "rng": copy.deepcopy(self.np_random.bit_generator.state),
        }

    def set_state(self, state: dict) -> None:
        self.position = state["position"].copy()
        self.goal = state["goal"].copy()
        self.np_random.bit_generator.state = copy.deepcopy(state["rng"])

    def render(self):
        size = 64
        frame = np.full((size, size, 3), 255, np.uint8)
        for point, colour in ((self.goal, (0, 160, 0)), (self.position, (200, 0, 0))):
            xy = np.zeros(2)
            xy[: min(2, self.dim)] = point[:2]
            i, j = ((xy + 1.0) / 2.0 * (size - 5)).astype(int)
            frame[size - 5 - j : size - j, i : i + 5] = colour
        return frame


def register() -> None:
    if "pliant-test/PointReach-v0" not in gym.registry:
        gym.register(
            id="pliant-test/PointReach-v0",
            entry_point="pliant.learn.toys:PointReachEnv",
            max_episode_steps=20,
        )


def point_reach_expert(env: gym.Env):
    """The optimal PointReach policy (behaviour-cloning tests): full speed towards the goal,
    the exact remaining distance on the last step; discrete: the axis with the largest gap."""
    space = env.action_space

    def act(obs: np.ndarray):
        dim = len(obs) // 2
        gap = obs[dim:] - obs[:dim]
        speed = env.unwrapped.speed
        if isinstance(space, gym.spaces.Discrete):
            axis = int(np.argmax(np.abs(gap)))
            if abs(gap[axis]) < speed / 2:
                return np.int64(2 * dim)
            return np.int64(2 * axis + (0 if gap[axis] > 0 else 1))
        return np.clip(gap / speed, -1.0, 1.0).astype(np.float32)

    return act
