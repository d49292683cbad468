"""The thesis' own Trunk comparison (§4.1.3, Fig. 4.6, L720-730): one goal per run, learning
judged by the cube's distance to it, the task solved (and the episode ended) under 5 mm. The
thesis pushes the cube to a goal along x and to one at (x, z), and reports the proxy pipeline
ending 2 mm from the goal against 4.5 mm for PPO directly on the FEM Trunk.

experiments/proxy/vs_fem_rl.py compares the two over 20 goals drawn at random (a policy that
must generalise); here each policy is learned for its goal, as the thesis' figure shows it:

1. PPO on the Trunk proxy (pliant/TrunkPushProxy-v0, bend_limit 0.2) with the goal fixed
   (goal_low = goal_high) and goal_tolerance 5 mm, experiments/proxy/rl.py's PPO settings and
   the thesis' budget (6700 steps of 0.3 s = 2e5 simulation steps); its greedy episode on the
   proxy, then the same policy through `pliant proxy transfer`'s loop on the FEM (thesis gains,
   episode ended at the first step that leaves the FEM's cube within 5 mm).
2. PPO directly on the FEM Trunk (pliant/TrunkPush-v0, proxy/vs_fem_rl.py's settings: 0.3 s
   steps, cable courses at the proxy's amplitude limit) with the same goal, tolerance, settings
   and budget; its greedy episode.

Both environments are deterministic for a fixed goal: one evaluation episode is the policy's
result. Each (goal, seed, side) is its own run (runs/fixed_goal/GOAL/seedS/SIDE, `--resume`
goes on from its last checkpoint); results in experiments/results/proxy/fixed_goal/GOAL/seedS/
(report_SIDE.json, the policy, its learning curve), then `--summary` gathers them
(summary.json, summary.png).

    python experiments/proxy/fixed_goal.py --goal x25 --seed 0 --side proxy
    python experiments/proxy/fixed_goal.py --goal x25 --seed 0 --side fem
    python experiments/proxy/fixed_goal.py --summary
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import shutil
import sys
import time
import warnings
from pathlib import Path

import numpy as np

from pliant import configure_threads
from pliant.learn.evaluate import load_policy
from pliant.learn.training import train
from pliant.learn.vec import make_env
from pliant.transfer.fem_rl import FEM_ENV, FEM_KWARGS, goal_kwargs, transfer_episode
from pliant.transfer.fem_rl import FIXED_GOAL_OUT as OUT
from pliant.transfer.fem_rl import FIXED_GOAL_TOLERANCE as TOLERANCE
from pliant.transfer.fem_rl import FIXED_GOALS as GOALS
from pliant.transfer.rl import SETTINGS, episode, rl_config
from pliant.viz import save_figure

# GOALS: offsets (x, z) in mm from the cube's settled start, inside the environments' draw
# box [5, 40] x [-30, 20]: one along x (the thesis' first case), two at (x, z).
THESIS = {"proxy_pipeline_mm": 2.0, "rl_on_fem_mm": 4.5}


def learn(side: str, goal: str, seed: int, env_steps: int, resume: bool) -> dict:
    """Train PPO on SIDE ("proxy" or "fem") for GOAL; its greedy result (and, for the proxy,
    the transfer's) in the report, which is written and returned."""
    offset = GOALS[goal]
    if side == "proxy":
        env_id, env_kwargs = SETTINGS["trunk"]["env_id"], dict(SETTINGS["trunk"]["env_kwargs"])
    else:
        env_id, env_kwargs = FEM_ENV, dict(FEM_KWARGS)
    env_kwargs.update(goal_kwargs(offset))
    config = rl_config("trunk", env_id, env_kwargs, env_steps, seed)
    config = dataclasses.replace(config, eval_freq=500, eval_episodes=1, checkpoint_freq=500)
    run_dir = Path("runs/fixed_goal") / goal / f"seed{seed}" / side
    result = train(None if resume else config, run_dir, resume=resume)
    out = OUT / goal / f"seed{seed}"
    policy_dir = out / side
    policy_dir.mkdir(parents=True, exist_ok=True)
    for f in ("model.zip", "vecnormalize.pkl", "meta.json"):
        shutil.copy(run_dir / "final" / f, policy_dir / f)
    shutil.copy(run_dir / "learning_curve.png", out / f"{side}_learning_curve.png")

    saved = load_policy(policy_dir)
    env = make_env(env_id, env_kwargs)

    def greedy(obs, k):
        return saved.model.predict(saved.normalize_obs(obs), deterministic=True)[0]

    own = episode(env, greedy, seed=0)
    curve = json.loads((run_dir / "evaluations.json").read_text())
    report = {
        "command": "python experiments/proxy/fixed_goal.py " + " ".join(sys.argv[1:]),
        "side": side,
        "goal": goal,
        "goal_offset_xz": list(offset),
        "tolerance_mm": TOLERANCE,
        "seed": seed,
        "env_id": env_id,
        "env_kwargs": env_kwargs,
        "env_steps": result.summary["steps"],
        "simulation_steps": result.summary["steps"] * env.unwrapped.substeps,
        "training_seconds": result.summary["wall_seconds"],
        "greedy_episode": own,
        # the first evaluation (environment steps) whose greedy episode ended solved
        "first_solved_at": next((c["step"] for c in curve if c["mean_length"] < 10), None),
        "curve": curve,
    }
    if side == "proxy":
        from pliant.transfer.proxy import TRUNK_GAINS

        report["transfer"] = transfer_episode(saved, offset, TRUNK_GAINS, TOLERANCE)
    path = out / f"report_{side}.json"
    path.write_text(json.dumps(report, indent=1))
    brief = {k: report[k] for k in ("side", "goal", "seed", "greedy_episode", "first_solved_at")}
    print(json.dumps({**brief, "transfer": report.get("transfer")}), flush=True)
    return report


def gather() -> dict:
    """Every goal and seed with both sides done: the FEM's final distance under the pipeline
    and under direct PPO."""
    rows = []
    for goal in GOALS:
        for seed_dir in sorted((OUT / goal).glob("seed*")):
            proxy, fem = seed_dir / "report_proxy.json", seed_dir / "report_fem.json"
            if not (proxy.exists() and fem.exists()):
                continue
            p, f = json.loads(proxy.read_text()), json.loads(fem.read_text())
            rows.append(
                {
                    "goal": goal,
                    "seed": p["seed"],
                    "proxy_on_proxy_mm": p["greedy_episode"]["distance"],
                    "pipeline_on_fem_mm": p["transfer"]["fem_distance"],
                    "pipeline_steps": p["transfer"]["steps"],
                    "rl_on_fem_mm": f["greedy_episode"]["distance"],
                    "rl_on_fem_steps": f["greedy_episode"]["length"],
                    "proxy_training_s": p["training_seconds"],
                    "fem_training_s": f["training_seconds"],
                    "proxy_first_solved_at": p["first_solved_at"],
                    "fem_first_solved_at": f["first_solved_at"],
                }
            )
    pipeline = np.array([r["pipeline_on_fem_mm"] for r in rows])
    direct = np.array([r["rl_on_fem_mm"] for r in rows])
    summary = {"rows": rows, "thesis": THESIS, "tolerance_mm": TOLERANCE}
    if rows:
        summary.update(
            pipeline_mean_mm=float(pipeline.mean()),
            rl_on_fem_mean_mm=float(direct.mean()),
            pipeline_solved=float(np.mean(pipeline < TOLERANCE)),
            rl_on_fem_solved=float(np.mean(direct < TOLERANCE)),
            pipeline_closer=int(np.sum(pipeline < direct)),
            pairs=len(rows),
        )
        if len(rows) >= 5:
            from scipy.stats import wilcoxon

            summary["wilcoxon_p"] = float(wilcoxon(pipeline, direct).pvalue)
    return summary


def plot(summary: dict, path: Path) -> None:
    from pliant.viz.render import offscreen_figure

    rows = summary["rows"]
    fig = offscreen_figure(8.0, 3.5)
    ax = fig.subplots()
    k = np.arange(len(rows))
    ax.bar(k - 0.2, [r["pipeline_on_fem_mm"] for r in rows], 0.4, label="proxy pipeline (FEM)")
    ax.bar(k + 0.2, [r["rl_on_fem_mm"] for r in rows], 0.4, label="PPO on the FEM")
    ax.axhline(TOLERANCE, color="g", lw=0.8, label="5 mm: solved")
    ax.set_xticks(k, [f"{r['goal']}\nseed {r['seed']}" for r in rows], fontsize=7)
    ax.set_ylabel("final cube-goal distance (mm)")
    ax.set_title("Trunk, one goal per run, 2e5 simulation steps each")
    ax.legend(fontsize=8)
    fig.tight_layout()
    save_figure(fig, path, dpi=90)


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--goal", choices=sorted(GOALS))
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--side", choices=("proxy", "fem"))
    parser.add_argument("--env-steps", type=int, default=SETTINGS["trunk"]["env_steps"])
    parser.add_argument("--resume", action="store_true")
    parser.add_argument("--summary", action="store_true", help="gather the finished runs")
    args = parser.parse_args()
    warnings.simplefilter("ignore")
    configure_threads(torch_threads=1)
    if args.summary:
        summary = gather()
        OUT.mkdir(parents=True, exist_ok=True)
        (OUT / "summary.json").write_text(json.dumps(summary, indent=1))
        if summary["rows"]:
            plot(summary, OUT / "summary.png")
        print(json.dumps({k: v for k, v in summary.items() if k != "rows"}, indent=1))
        return
    if args.goal is None or args.side is None:
        parser.error("--goal and --side (or --summary)")
    clock = time.perf_counter()
    learn(args.side, args.goal, args.seed, args.env_steps, args.resume)
    print(f"{time.perf_counter() - clock:.0f} s", flush=True)


if __name__ == "__main__":
    main()
