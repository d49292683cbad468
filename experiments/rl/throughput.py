"""Learning throughput on CartStemContact: environment steps per second of SAC training
(MLP 3 x 512, one gradient step per collection, batch 256) with 1 and 2 subprocess workers
and with 2 local Ray actors, beside the environment alone. "1 worker" steps its environment
in the learner's process (a worker process costs more than it saves for one environment).

    PYTHONPATH=. python experiments/rl/throughput.py [--steps 600]

Timed from step 100 of each run (after the workers' start and the kernels' compilation);
SAC's gradient steps start at step 100. Writes experiments/results/rl/throughput.json.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import tempfile
import time
from pathlib import Path

from stable_baselines3.common.callbacks import BaseCallback

from pliant import configure_threads
from pliant.learn import load_config, train
from pliant.learn.vec import make_env

ENV = "pliant/CartStemContact-v0"
OUT = Path("experiments/results/rl/throughput.json")


class Stopwatch(BaseCallback):
    def __init__(self, start: int) -> None:
        super().__init__()
        self.start, self.t0, self.s0 = start, None, None

    def _on_step(self) -> bool:
        if self.t0 is None and self.num_timesteps >= self.start:
            self.t0, self.s0 = time.perf_counter(), self.num_timesteps
        return True

    def rate(self) -> float:
        return (self.num_timesteps - self.s0) / (time.perf_counter() - self.t0)


def environment_alone(steps: int) -> float:
    env = make_env(ENV)
    env.reset(seed=0)
    for _ in range(5):
        env.step(env.action_space.sample())
    clock = time.perf_counter()
    for _ in range(steps):
        *_, terminated, truncated, _ = env.step(env.action_space.sample())
        if terminated or truncated:
            env.reset()
    return steps / (time.perf_counter() - clock)


def training(n_envs: int, vec_env: str, steps: int) -> float:
    config = load_config(
        ENV,
        "SAC",
        overrides={
            "total_timesteps": steps,
            "n_envs": n_envs,
            "vec_env": vec_env,
            "eval_episodes": 0,
            "checkpoint_freq": 0,
            "video_episodes": 0,
            "hyperparams": {"learning_starts": 100},
        },
    )
    watch = Stopwatch(100)
    with tempfile.TemporaryDirectory() as folder:
        train(config, folder, extra_callbacks=[watch])
    return watch.rate()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--steps", type=int, default=600)
    parser.add_argument("--no-ray", action="store_true")
    args = parser.parse_args()
    configure_threads(torch_threads=1)
    rows = {"environment alone (1 process)": environment_alone(args.steps)}
    for n_envs, vec_env in [(1, "subproc"), (2, "subproc")] + ([] if args.no_ray else [(2, "ray")]):
        label = f"SAC training, {n_envs} {'Ray actor' if vec_env == 'ray' else 'worker'}(s)"
        rows[label] = training(n_envs, vec_env, args.steps)
        print(f"{label}: {rows[label]:.2f} env steps/s", flush=True)
    OUT.parent.mkdir(parents=True, exist_ok=True)
    report = {
        "env_steps_per_second": rows,
        "machine": f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores"
        f" shared with other jobs (load average {os.getloadavg()[0]:.1f})",
        "steps_per_run": args.steps,
    }
    OUT.write_text(json.dumps(report, indent=1))
    print(json.dumps(report, indent=1))


if __name__ == "__main__":
    main()
