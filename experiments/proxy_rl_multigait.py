"""PPO on the Multigait proxy (thesis §4.1.3: RL on the proxy, about 2e4 simulation steps for
the Multigait): the learned policy's forward travel over one 6-action episode (3.6 s) beside
the hand gait's and a random policy's, on the proxy.

    python experiments/proxy_rl_multigait.py [--env-steps 2000] [--seed 0]

One environment step is 60 simulation steps (0.6 s); --env-steps 334 is the thesis' budget.
Results: experiments/results/proxy_rl_multigait.json.
"""

from __future__ import annotations

import argparse
import json
import time
import warnings
from pathlib import Path

import gymnasium as gym
import numpy as np
from stable_baselines3 import PPO

import pliant.envs  # noqa: F401  (registers the environments)

HAND_GAIT = [4, 0, 2, 5, 1, 3]  # rear, centre, front inflated, then deflated in that order


def travel(env: gym.Env, policy) -> float:
    obs, _ = env.reset(seed=0)
    total = 0.0
    for k in range(6):
        obs, reward, terminated, truncated, _ = env.step(policy(obs, k))
        total += reward
        if terminated or truncated:
            break
    return total


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--env-steps", type=int, default=2000)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--out", type=Path, default=Path("experiments/results/proxy_rl_multigait.json")
    )
    args = parser.parse_args()
    warnings.simplefilter("ignore")
    env = gym.make("pliant/MultigaitProxy-v0")
    rng = np.random.default_rng(args.seed)
    hand = travel(env, lambda obs, k: HAND_GAIT[k])
    random = float(np.mean([travel(env, lambda obs, k: int(rng.integers(6))) for _ in range(5)]))
    model = PPO("MlpPolicy", env, n_steps=120, batch_size=60, gamma=0.99, seed=args.seed)
    start = time.perf_counter()
    model.learn(total_timesteps=args.env_steps)
    seconds = time.perf_counter() - start
    actions: list[int] = []

    def greedy(obs, k: int) -> int:
        actions.append(int(model.predict(obs, deterministic=True)[0]))
        return actions[-1]

    learned = travel(env, greedy)
    report = {
        "env_steps": args.env_steps,
        "simulation_steps": 60 * args.env_steps,
        "training_seconds": seconds,
        "travel_mm": {"learned": learned, "hand_gait": hand, "random_mean_of_5": random},
        "learned_actions": actions,
        "seed": args.seed,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(report, indent=2))
    print(json.dumps(report, indent=2))


if __name__ == "__main__":
    main()
