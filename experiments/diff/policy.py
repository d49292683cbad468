"""Analytic policy gradients against PPO on Diamond reaching, in environment steps.

    python experiments/diff/policy.py [--quick] [--fresh] [--out FILE]

The environment is pliant/Diamond-v0 with continuous absolute actions (the four cable
displacements in [0, 20] mm, ramped over 5 solver steps of 0.01 s), the Diamond at mesh size
20 mm, goals uniform in [-30, 30] x [-30, 30] x [125, 145] mm, an episode of at most 50 steps,
success as the environment defines it: the effector within 5 mm of the goal (terminated,
``info["is_success"]``).

* **APG** (analytic policy gradients): an MLP (the 18 observations of the environment, computed
  from the state in torch, 2 x 64 tanh, 4 tanh outputs mapped to the displacements as the
  environment maps actions) trained by Adam on the exact gradient of one episode's loss, the
  mean effector-goal distance over `--horizon` control steps (pliant.diff.policy.closed_loop:
  the same ramps and solver steps, "fresh" tangent; each episode's backward pass is its
  adjoint sweep). One training episode counts `--horizon` environment steps.
* **PPO** (stable-baselines3, MlpPolicy, its defaults but n_steps = 128, batch 64; 32 and 32
  with --quick) on the environment itself.

Both are evaluated at the same environment-step budgets on held-out goals drawn after training
from a separate seed (2026), deterministic actions, in the environment ("lagged" tangent, as
RL runs it): the success rate and the mean final distance. Writes the curves after each
evaluation (atomically) with a checkpoint of each learner, so that a run cut short resumes
where it stopped (--fresh starts again). Timings are wall-clock on the shared 2-core machine.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import gymnasium as gym
import numpy as np
import torch

import pliant.envs  # noqa: F401  (registers the environments)
from pliant.diff.policy import closed_loop, embedded_positions
from pliant.files import write_json
from pliant.solvers import ImplicitEuler

ROOT = Path(__file__).resolve().parents[2]
OUT = ROOT / "experiments" / "results" / "diff" / "policy.json"
ENV_ID = "pliant/Diamond-v0"
ENV_KWARGS = {"action_type": "continuous", "continuous_mode": "absolute", "mesh_size": 20.0}
EVAL_SEED = 2026


class MLP(torch.nn.Module):
    def __init__(self, n_in: int, n_out: int, width: int = 64) -> None:
        super().__init__()
        self.net = torch.nn.Sequential(
            torch.nn.Linear(n_in, width),
            torch.nn.Tanh(),
            torch.nn.Linear(width, width),
            torch.nn.Tanh(),
            torch.nn.Linear(width, n_out),
            torch.nn.Tanh(),
        ).double()

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        return self.net(obs)


def observation(env, q: torch.Tensor, goal: torch.Tensor) -> torch.Tensor:
    """The environment's observation (DiamondEnv._observe) from positions, in torch."""
    model = env.model
    points = [embedded_positions(model.effectors[0].points, q)[0]]
    points += [embedded_positions(a.points, q)[0] for a in model.actuators]
    return torch.cat([*points, goal]) / env.length_scale


def evaluate(env, act, goals: np.ndarray) -> dict:
    """Success rate and mean final distance of the deterministic policy `act(obs)` over the
    goals, in the environment."""
    successes, finals = [], []
    for goal in goals:
        obs, _ = env.reset(options={"goal": goal})
        info = {"distance": env.unwrapped.distance(), "is_success": False}
        done = False
        while not done:
            obs, _, terminated, truncated, info = env.step(act(obs))
            done = terminated or truncated
        successes.append(bool(info.get("is_success", False)))
        finals.append(float(env.unwrapped.distance()))
    return {"success_rate": float(np.mean(successes)), "final_distance_mm": float(np.mean(finals))}


def train_apg(args, env, eval_env, goals, record, folder: Path):
    inner = env.unwrapped
    model = inner.model
    solver = ImplicitEuler(model, inner.dt, tangent="fresh")
    env.reset(seed=0)
    start = inner.state.copy()
    policy = MLP(18, model.n_actuators)
    optimiser = torch.optim.Adam(policy.parameters(), lr=args.apg_lr)
    rng = np.random.default_rng(0)
    done = record.setdefault("apg", {"curve": [], "steps": 0, "episodes": 0, "seconds": 0.0})
    checkpoint = folder / "apg.pt"
    if checkpoint.exists() and done["steps"]:
        saved = torch.load(checkpoint, weights_only=False)
        policy.load_state_dict(saved["policy"])
        optimiser.load_state_dict(saved["optimiser"])
        rng.bit_generator.state = saved["rng"]
    max_commands = torch.as_tensor(inner.max_commands)

    def act(obs):
        with torch.no_grad():
            return policy(torch.as_tensor(obs, dtype=torch.float64)).numpy()

    while done["steps"] < args.steps:
        clock = time.perf_counter()
        goal = torch.as_tensor(rng.uniform(inner.goal_low, inner.goal_high))

        def command(q, v, n, goal=goal):
            return 0.5 * (policy(observation(inner, q, goal)) + 1.0) * max_commands

        episode = closed_loop(model, solver, start, command, args.horizon, substeps=inner.substeps)
        effector = model.effectors[0].points
        reached = torch.stack([embedded_positions(effector, q)[0] for q, _ in episode[1:]])
        loss = torch.linalg.norm(reached - goal, dim=1).mean() / 10.0
        optimiser.zero_grad()
        loss.backward()
        optimiser.step()
        done["steps"] += args.horizon
        done["episodes"] += 1
        done["seconds"] += time.perf_counter() - clock
        done.setdefault("losses", []).append(float(loss.detach()) * 10.0)
        if done["steps"] % args.eval_every < args.horizon or done["steps"] >= args.steps:
            torch.save(
                {
                    "policy": policy.state_dict(),
                    "optimiser": optimiser.state_dict(),
                    "rng": rng.bit_generator.state,
                },
                checkpoint,
            )
            result = {"env_steps": done["steps"], "train_seconds": done["seconds"]}
            result.update(evaluate(eval_env, act, goals))
            done["curve"].append(result)
            print("APG", result, flush=True)
            yield


def train_ppo(args, env, eval_env, goals, record, folder: Path):
    from stable_baselines3 import PPO

    done = record.setdefault("ppo", {"curve": [], "steps": 0, "seconds": 0.0})
    checkpoint = folder / "ppo.zip"
    if checkpoint.exists() and done["steps"]:
        agent = PPO.load(checkpoint, env=env)
    else:
        rollout = min(128, args.steps)
        agent = PPO("MlpPolicy", env, n_steps=rollout, batch_size=min(64, rollout), seed=0)

    def act(obs):
        return agent.predict(obs, deterministic=True)[0]

    while done["steps"] < args.steps:
        clock = time.perf_counter()
        chunk = min(args.eval_every, args.steps - done["steps"])
        agent.learn(chunk, reset_num_timesteps=False)
        done["steps"] = int(agent.num_timesteps)
        done["seconds"] += time.perf_counter() - clock
        agent.save(checkpoint)
        result = {"env_steps": done["steps"], "train_seconds": done["seconds"]}
        result.update(evaluate(eval_env, act, goals))
        done["curve"].append(result)
        print("PPO", result, flush=True)
        yield


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="a few episodes, 2 goals")
    parser.add_argument("--fresh", action="store_true", help="start again, ignoring the file")
    parser.add_argument("--steps", type=int, default=240, help="environment steps each")
    parser.add_argument("--eval-every", type=int, default=240)
    parser.add_argument("--eval-goals", type=int, default=4)
    parser.add_argument("--horizon", type=int, default=8, help="APG episode, control steps")
    parser.add_argument("--apg-lr", type=float, default=3e-3)
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    if args.quick:
        args.steps, args.eval_every, args.eval_goals, args.horizon = 32, 32, 1, 4
    out = args.out or (ROOT / "out" / "diff" / "policy_quick.json" if args.quick else OUT)
    folder = out.with_suffix("") if not args.quick else out.parent / "policy_quick"
    folder.mkdir(parents=True, exist_ok=True)
    record = {} if args.fresh or not out.exists() else json.loads(out.read_text())
    env, eval_env = gym.make(ENV_ID, **ENV_KWARGS), gym.make(ENV_ID, **ENV_KWARGS)
    inner = env.unwrapped
    # Held-out goals: drawn after (and apart from) training, from their own seed.
    goals = np.random.default_rng(EVAL_SEED).uniform(
        inner.goal_low, inner.goal_high, (args.eval_goals, 3)
    )
    record["setting"] = {
        "env": ENV_ID,
        "env_kwargs": ENV_KWARGS,
        "success": f"effector within {inner.goal_tolerance} mm of the goal (terminated)",
        "episode_steps": env.spec.max_episode_steps,
        "eval_goals": args.eval_goals,
        "eval_seed": EVAL_SEED,
        "budget_env_steps": args.steps,
        "apg_horizon": args.horizon,
        "apg_lr": args.apg_lr,
        "ppo": "stable-baselines3 PPO, MlpPolicy, n_steps min(128, budget), batch 64, seed 0",
        "command": "python experiments/diff/policy.py" + (" --quick" if args.quick else ""),
    }
    for name, learner in (("apg", train_apg), ("ppo", train_ppo)):
        for _ in learner(args, env, eval_env, goals, record, folder):
            write_json(out, record)
        summary = record[name]
        summary["env_steps_per_s"] = summary["steps"] / max(summary["seconds"], 1e-9)
        summary["best_success_rate"] = max(r["success_rate"] for r in summary["curve"])
        write_json(out, record)
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
