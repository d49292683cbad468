"""Plain SAC on the whole task, the thesis' baseline (same SAC, same hyper-parameters)."""

from __future__ import annotations

from pathlib import Path

import gymnasium as gym
import numpy as np
import torch

from pliant.files import atomic_path, read_checked
from pliant.learn.graph.hierarchy import (
    GraphConfig,
    check_schedule,
    episode_means,
    train_and_evaluate,
)
from pliant.learn.graph.sac import SAC, ReplayBuffer


class FlatSAC:
    """One SAC agent with the :class:`GraphAgent` interface (learn, evaluate, save)."""

    def __init__(
        self,
        observation_space: gym.spaces.Box,
        action_space: gym.spaces.Box,
        config: GraphConfig | None = None,
        *,
        seed: int = 0,
    ) -> None:
        torch.manual_seed(seed)
        self.rng = np.random.default_rng(seed)
        self.config = c = config or GraphConfig()
        check_schedule(c)
        self._update_debt = 0.0
        self.low, self.high = action_space.low, action_space.high
        obs_dim, act_dim = observation_space.shape[0], action_space.shape[0]
        self.sac = SAC(obs_dim, act_dim, hidden=c.hidden, lr=c.lr, gamma=c.gamma, tau=c.tau)
        self.buffer = ReplayBuffer(
            c.buffer_size, obs=(obs_dim,), action=(act_dim,), reward=(), next_obs=(obs_dim,),
            done=(),
        )  # fmt: skip
        self.steps = 0
        self.next_eval: int | None = None  # as GraphAgent.next_eval

    def run_episode(self, env: gym.Env, *, train: bool, seed: int | None = None) -> dict:
        c = self.config
        obs, _ = env.reset(seed=seed)
        total, length, done, success = 0.0, 0, False, False
        while not done:
            if train and self.steps < c.learning_starts:
                action = self.rng.uniform(-1.0, 1.0, size=self.low.shape).astype(np.float32)
            else:
                action = self.sac.act(obs, deterministic=not train)
            scaled = self.low + 0.5 * (np.clip(action, -1, 1) + 1.0) * (self.high - self.low)
            next_obs, reward, terminated, truncated, info = env.step(scaled)
            total, length = total + float(reward), length + 1
            done = terminated or truncated
            success = success or bool(info.get("is_success", terminated))
            if train:
                self.buffer.add(obs=obs, action=action, reward=reward, next_obs=next_obs,
                                done=float(terminated))  # fmt: skip
                self.steps += 1
                if self.steps >= c.learning_starts and not c.updates_per_episode:
                    self._update_debt += c.updates_per_step
                    while self._update_debt >= 1.0:
                        self._update_debt -= 1.0
                        self._update()
            obs = next_obs
        if train and c.updates_per_episode and self.steps >= c.learning_starts:
            for _ in range(c.updates_per_episode):
                self._update()
        return {"return": total, "length": length, "success": success, "info": info}

    def _update(self) -> None:
        if len(self.buffer) >= self.config.batch_size:
            b = self.buffer.sample(self.config.batch_size, self.rng)
            self.sac.update(b["obs"], b["action"], b["reward"], b["next_obs"], b["done"])

    def learn(self, env, total_steps, *, eval_env=None, eval_every=0, eval_episodes=5,
              callback=None) -> list[dict]:  # fmt: skip
        return train_and_evaluate(
            self, env, total_steps, eval_env, eval_every, eval_episodes, callback
        )

    def save(self, path: str | Path) -> None:
        state = {"steps": self.steps, "rng": self.rng.bit_generator.state}
        state |= {"update_debt": self._update_debt, "next_eval": self.next_eval}
        state |= {"sac": self.sac.checkpoint(), "buffer": self.buffer.state_dict()}
        with atomic_path(path) as tmp:
            torch.save(state | {"torch_rng": torch.get_rng_state()}, tmp)

    def load(self, path: str | Path) -> None:
        state = read_checked(
            path, lambda p: torch.load(p, weights_only=False), "a graph agent checkpoint"
        )
        self.steps, self.rng.bit_generator.state = state["steps"], state["rng"]
        self._update_debt = state.get("update_debt", 0.0)  # older checkpoints: whole rates
        self.next_eval = state.get("next_eval")
        self.sac.restore(state["sac"])
        self.buffer.load_state_dict(state["buffer"])
        torch.set_rng_state(state["torch_rng"])

    def evaluate(self, env: gym.Env, episodes: int = 5, seed: int = 10_000) -> dict:
        runs = [self.run_episode(env, train=False, seed=seed + k) for k in range(episodes)]
        return episode_means(runs)
