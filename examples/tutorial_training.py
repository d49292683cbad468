"""Tutorial: reinforcement learning. Train PPO (Stable-Baselines3) on CartStem, a fast
environment (a soft stem on a cart, rewarded +1 for each step it stays up), then evaluate the
saved policy against random actions."""

import json
import tempfile
from pathlib import Path

import gymnasium as gym
import numpy as np
from _common import QUICK, save_figure

import pliant.envs  # noqa: F401  registers pliant/<Name>-v0
from pliant.learn import load_config, train
from pliant.learn.evaluate import evaluate_saved
from pliant.viz.render import offscreen_figure

ENV = "pliant/CartStem-v0"
steps = 384 if QUICK else 2048  # QUICK (CI): three rollouts of 128 steps
config = load_config(
    ENV,
    "PPO",
    overrides={
        "total_timesteps": steps,
        "n_envs": 1,  # worker processes: 1 steps the environment in this process
        "vec_env": "dummy",
        "eval_freq": 192 if QUICK else 128,  # evaluations along the way: the learning curve
        "eval_episodes": 2 if QUICK else 5,
        "checkpoint_freq": steps,
        "video_episodes": 0,
        "seed": 0,
        "hyperparams": {"n_steps": 128, "batch_size": 64, "learning_rate": 1e-3},
    },
)

with tempfile.TemporaryDirectory() as folder:
    run = Path(folder) / "cartstem"
    result = train(config, run)  # writes the run folder: checkpoints, best/, final/, logs
    curve = json.loads((run / "evaluations.json").read_text())
    trained = evaluate_saved(run / "final", episodes=2 if QUICK else 20)

env = gym.make(ENV)
random_returns = []
for seed in range(2 if QUICK else 20):
    env.reset(seed=10_000 + seed)
    env.action_space.seed(seed)
    total, done = 0.0, False
    while not done:
        _, reward, terminated, truncated, _ = env.step(env.action_space.sample())
        total, done = total + reward, terminated or truncated
    random_returns.append(total)
print(
    f"PPO after {steps} steps: mean return {np.mean(trained.returns):.1f}"
    f" (random actions {np.mean(random_returns):.1f}; 80 is the whole episode)"
)

fig = offscreen_figure(6.0, 3.5)
ax = fig.add_subplot(1, 1, 1)
ax.plot(
    [e["step"] for e in curve], [e["mean_return"] for e in curve], "o-", label="PPO (evaluation)"
)
ax.axhline(np.mean(random_returns), color="0.5", ls=":", label="random actions")
ax.set_xlabel("training steps")
ax.set_ylabel("mean return")
ax.set_title("CartStem: steps the stem stays up (of 80)")
ax.legend()
ax.grid(alpha=0.3)
save_figure(fig, "training_cartstem.png")
