"""Table 3.2's hand-defined row: the hand gait as six discrete actions of the Multigait
environment (rear pair, centre, front pair inflated, then deflated in that order), on the
reduced model (pliant/ReducedMultigait-v0) and on the full one (pliant/Multigait-v0, SofaGym's
reward), default mesh.

    OPENBLAS_NUM_THREADS=1 nice python experiments/reduction/hand_episode.py [--reduced-model F]

Reported: cumulative reward (sum of max(0, dx)) and final forward travel of the centre of
mass on both, in mm (the thesis: reduced 53.8 / 32.4, complete 35.6 mm final x, on SofaGym's
reference mesh and its command sizes). Writes experiments/results/reduction/hand_episode.json.
"""

from __future__ import annotations

import argparse
import json
import time
import warnings
from pathlib import Path

import gymnasium as gym

import pliant.envs  # noqa: F401  (registers the environments)

HAND = [4, 0, 2, 5, 1, 3]  # rear, centre, front inflated; then deflated in that order


def episode(env_id: str, **kwargs) -> dict:
    env = gym.make(env_id, **kwargs)
    env.reset(seed=0)
    rewards = []
    began, cpu = time.perf_counter(), time.process_time()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for action in HAND:
            _, reward, _, truncated, info = env.step(action)
            rewards.append(reward)
            if truncated:
                break
    steps = len(rewards) * env.unwrapped.substeps
    return {
        "rewards_mm": rewards,
        "cumulative_reward_mm": sum(rewards),
        "final_travel_mm": info.get("travelled"),
        "sim_steps_per_s": steps / (time.perf_counter() - began),
        "sim_steps_per_cpu_s": steps / (time.process_time() - cpu),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--reduced-model", type=Path, default=None)
    parser.add_argument("--out", type=Path, default=Path("experiments/results/reduction"))
    args = parser.parse_args()
    results = {
        "actions": HAND,
        "reduced": episode("pliant/ReducedMultigait-v0", reduced_model=args.reduced_model),
        "full": episode("pliant/Multigait-v0", reward="sofagym"),
    }
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "hand_episode.json").write_text(json.dumps(results, indent=1))
    for name in ("reduced", "full"):
        r = results[name]
        print(
            f"{name}: cumulative reward {r['cumulative_reward_mm']:.2f} mm, final travel"
            f" {r['final_travel_mm']:.2f} mm, {r['sim_steps_per_s']:.0f} steps/s"
            f" ({r['sim_steps_per_cpu_s']:.0f} per CPU second)"
        )


if __name__ == "__main__":
    main()
