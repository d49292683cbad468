"""Diamond reaching by RL against Table 3.1's inverse QP and OPD (issue 16).

    PYTHONPATH=. python experiments/rl/diamond_rl.py [--steps 100000]

Trains PPO (SB3 defaults: MLP 2 x 64, n_steps 2048) on pliant/Diamond-v0 as the environment
defines it (the Table 3.1 mesh, 13 mm; one cable pulled or released by 1 mm per action, 5
steps of 0.01 s; goals drawn in SofaGym's box, reward Eq. 3.2, an episode of 50 actions ends
within 5 mm), in one process, checkpointing every 10000 steps in runs/diamond_ppo (not
committed; the same command resumes a stopped run). Then runs the greedy policy from rest on
Table 3.1's five reachable goals (experiments/planning/table_3_1.py, same seed) for the 50
actions of an episode without the 5 mm stop, and reports per goal the closest and final
distance, the actions and wall time to 5 mm and to 1 mm, and the time per decision (the
network alone, and with the simulation), beside the QP and OPD rows of
experiments/results/planning/table_3_1.json. Writes experiments/results/rl/diamond_ppo/.
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import time
from pathlib import Path

import numpy as np

from pliant import configure_threads
from pliant.envs import make
from pliant.learn import load_config, train
from pliant.learn.plots import plot_learning_curve

RESULTS = Path("experiments/results/rl/diamond_ppo")
TABLE_3_1 = Path("experiments/results/planning/table_3_1.json")


def reach(model, goal: np.ndarray, actions: int) -> dict:
    """The greedy policy from rest towards `goal` for `actions` actions, without the stop."""
    env = make("pliant/Diamond-v0", goal_tolerance=1e-9)
    obs, info = env.reset(seed=0, options={"goal": goal})
    distances, network_s = [env.unwrapped.distance()], []
    clock = time.perf_counter()
    first = {5.0: None, 1.0: None}
    for k in range(1, actions + 1):
        tick = time.perf_counter()
        action, _ = model.predict(obs, deterministic=True)
        network_s.append(time.perf_counter() - tick)
        obs, _, terminated, truncated, info = env.step(action)
        distances.append(info["distance"])
        for tol in first:
            if first[tol] is None and info["distance"] <= tol:
                first[tol] = (k, time.perf_counter() - clock)
        if terminated or truncated:
            break
    total = time.perf_counter() - clock
    return {
        "goal": goal.tolist(),
        "closest_mm": float(min(distances)),
        "final_mm": float(distances[-1]),
        "actions_to_5mm": None if first[5.0] is None else first[5.0][0],
        "seconds_to_5mm": None if first[5.0] is None else first[5.0][1],
        "actions_to_1mm": None if first[1.0] is None else first[1.0][0],
        "seconds_to_1mm": None if first[1.0] is None else first[1.0][1],
        "network_ms_per_decision": 1e3 * float(np.median(network_s)),
        "ms_per_decision_with_simulation": 1e3 * total / len(network_s),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=100_000)
    parser.add_argument("--run", type=Path, default=Path("runs/diamond_ppo"))
    args = parser.parse_args()
    configure_threads(torch_threads=1)
    resume = (args.run / "checkpoints").exists() and any((args.run / "checkpoints").glob("step_*"))
    config = load_config(
        "pliant/Diamond-v0",
        "PPO",
        overrides={
            "total_timesteps": args.steps,
            "n_envs": 1,
            "vec_env": "dummy",
            "eval_freq": 10_000,
            "eval_episodes": 20,
            "checkpoint_freq": 10_000,
        },
    )
    result = train(config, args.run, resume=resume, total_timesteps=args.steps)
    from stable_baselines3 import PPO

    model = PPO.load(args.run / "final" / "model.zip", device="cpu")
    table = json.loads(TABLE_3_1.read_text())
    runs = [reach(model, np.array(r["goal"]), 50) for r in table["runs"]]
    summary = {
        "env_id": "pliant/Diamond-v0",
        "algo": "PPO, SB3 defaults (MLP 2x64)",
        "training": result.summary,
        "table_3_1_goals": runs,
        "table_3_1_qp_seconds_to_1mm": [r["qp"]["time_to_tolerance_s"] for r in table["runs"]],
        "table_3_1_opd_seconds_to_1mm": [r["opd"]["time_s"] for r in table["runs"]],
        "command": f"PYTHONPATH=. python experiments/rl/diamond_rl.py --steps {args.steps}",
    }
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / "summary.json").write_text(json.dumps(summary, indent=1))
    for name in ("evaluations.json", "eval.gif", "config.yaml"):
        if (args.run / name).exists():
            shutil.copy(args.run / name, RESULTS / name)
    if (args.run / "evaluations.json").exists():
        plot_learning_curve(args.run, RESULTS / "learning_curve.png", title="Diamond, PPO")
    print(json.dumps(runs, indent=1))


if __name__ == "__main__":
    sys.exit(main())
