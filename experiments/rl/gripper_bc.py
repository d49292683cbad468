"""Gripper: recurrent PPO with and without behaviour-cloning pre-training (thesis §3.2.1,
Fig. 3.7-3.8: LSTM 128, converged after 1.4e6 steps; cloning the hand-designed 4-phase grasp,
3000 epochs, speeds learning up).

    PYTHONPATH=. python experiments/rl/gripper_bc.py [--steps 60000] [--threshold 0.8]

Two runs of the environment's configuration (pliant/learn/configs/Gripper.yaml: RecurrentPPO,
LSTM 128, VecNormalize, 2 workers) with the same seed, one of them pre-trained (3000 epochs) on
the successful ones of 30 episodes of :func:`pliant.envs.gripper.expert` (the expert fails in
about a quarter of them, and a failed episode runs its 250 steps: kept, they would be 80 % of
the pairs). Each is evaluated (10 deterministic episodes, random cube offsets and goals) before
training and every `--eval-freq` steps. The report is the number of steps each run takes to
reach `--threshold` success, beside the thesis' budget. Runs checkpoint in
runs/gripper_{scratch,bc} (not committed) and resume with the same command; results in
experiments/results/rl/gripper_bc/.

``--push-down``: the thesis' random downward force on the cube (``cube_push_down``, up to
``push_force`` = 50 mN a step), which it needed for a firm grasp; runs in
runs/gripper_{scratch,bc}_push_down, results in experiments/results/rl/gripper_bc_push_down/.

``--sofagym-reward``: SofaGym's reward instead of the thesis' (``reward="sofagym"``: the
decrease of the height error over the step divided by 20, clipped to [0, 1], plus 1 on
success), the other difference from the thesis' set-up; runs and results with the suffix
``_sofagym_reward`` (after ``_push_down`` when both are given).

Both final policies are kept beside the results (``policy_bc.npz``, ``policy_scratch.npz``:
the LSTM actor and the observation statistics, ``pliant.learn.kept``); ``--evaluate FOLDER``
re-evaluates them as the runs' final evaluations did (``--eval-episodes`` deterministic
episodes, seed 10 000 on) into ``--out``/summary.json, and exits:

    PYTHONPATH=. python experiments/rl/gripper_bc.py --evaluate \
        experiments/results/rl/gripper_bc --out /tmp/gripper_bc
"""

from __future__ import annotations

import argparse
import csv
import json
import shutil
from pathlib import Path

import numpy as np
from stable_baselines3.common.callbacks import BaseCallback

from pliant import configure_threads
from pliant.learn import load_config, train
from pliant.learn.evaluate import evaluate_saved, export_run, run_episodes
from pliant.learn.vec import make_env
from pliant.viz import save_figure

RESULTS = Path("experiments/results/rl/gripper_bc")
EVAL_SEED = 10_000  # pliant.learn's evaluations: episode k resets with seed 10 000 + k
THESIS = {"algo": "RecurrentPPO, LSTM 128", "steps_to_converge": 1_400_000, "bc_epochs": 3000}


class EvaluateAtStart(BaseCallback):
    """The policy as training starts (after the cloning, if any), evaluated like the run's
    evaluations, written to ``start_evaluation.json`` (once: a resumed run skips it)."""

    def __init__(self, run: Path, episodes: int, env_id: str, env_kwargs: dict) -> None:
        super().__init__()
        self.path = run / "start_evaluation.json"
        self.episodes, self.env_id, self.env_kwargs = episodes, env_id, env_kwargs

    def _on_training_start(self) -> None:
        if self.path.exists() or self.model.num_timesteps > 0:
            return
        env = make_env(self.env_id, self.env_kwargs)
        vecnorm = self.model.get_vec_normalize_env()
        result = run_episodes(
            self.model,
            env,
            self.episodes,
            normalize_obs=None if vecnorm is None else vecnorm.normalize_obs,
            seed=EVAL_SEED,
        )
        env.close()
        self.path.write_text(json.dumps({"step": 0, **result.to_dict()}, indent=1))

    def _on_step(self) -> bool:
        return True


def steps_to(curve: list[dict], threshold: float) -> int | None:
    return next((e["step"] for e in curve if (e.get("success_rate") or 0.0) >= threshold), None)


def training_steps_to(episodes_csv: Path, threshold: float, window: int = 20) -> int | None:
    """The step at which the success rate of the last `window` training episodes (stochastic
    policy, in ``episodes.csv``) first reaches `threshold`: a finer clock than evaluations."""
    with open(episodes_csv) as f:
        rows = list(csv.DictReader(f))
    success = [r["success"] == "1" for r in rows]
    for k in range(window, len(rows) + 1):
        if sum(success[k - window : k]) >= threshold * window:
            return int(float(rows[k - 1]["step"]))
    return None


def folder_of(runs: Path, name: str) -> Path:
    return runs / f"gripper_{name}"


def variant(args) -> str:
    """The suffix of the runs' and results' folders: the options that change the task."""
    return "_push_down" * args.push_down + "_sofagym_reward" * args.sofagym_reward


def results_of(args) -> Path:
    if args.out is not None:
        return args.out
    return RESULTS.with_name(RESULTS.name + variant(args))


def run_name(name: str, args) -> str:
    return name + variant(args)


def run(name: str, bc: bool, args) -> dict:
    folder = folder_of(args.runs, run_name(name, args))
    resume = (folder / "checkpoints").exists() and any((folder / "checkpoints").glob("step_*"))
    overrides = {
        "total_timesteps": args.steps,
        "eval_freq": args.eval_freq,
        "eval_episodes": args.eval_episodes,
        "checkpoint_freq": args.eval_freq,
        "video_episodes": 0,
    }
    if bc:
        overrides["bc"] = {
            "expert": "pliant.envs.gripper:expert",
            "episodes": args.expert_episodes,
            "successful_only": True,
            "epochs": args.bc_epochs,
        }
    config = load_config("pliant/Gripper-v0", "RecurrentPPO", overrides=overrides)
    if args.push_down:
        config.env_kwargs = {**config.env_kwargs, "cube_push_down": True}
    if args.sofagym_reward:
        config.env_kwargs = {**config.env_kwargs, "reward": "sofagym"}
    start = EvaluateAtStart(folder, args.eval_episodes, config.env_id, config.env_kwargs)
    result = train(
        config, folder, resume=resume, total_timesteps=args.steps, extra_callbacks=[start]
    )
    curve = [json.loads(start.path.read_text())] if start.path.exists() else []
    curve += json.loads((folder / "evaluations.json").read_text())
    out = {
        "behaviour_cloning": json.loads((folder / "bc.json").read_text()) if bc else None,
        "curve": [
            {k: e[k] for k in ("step", "success_rate", "mean_return", "mean_length")} for e in curve
        ],
        "steps_to_threshold": steps_to(curve, args.threshold),
        "training_steps_to_threshold": training_steps_to(folder / "episodes.csv", args.threshold),
        "training": result.summary,
    }
    shutil.copy(folder / "evaluations.json", results_of(args) / f"evaluations_{name}.json")
    return out


def plot(runs: dict, folder: Path, threshold: float, path: Path, suffix: str = "") -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 3.6))
    for (name, r), colour in zip(runs.items(), ("C0", "C1"), strict=False):
        steps = [e["step"] for e in r["curve"]]
        success = [100 * (e["success_rate"] or 0.0) for e in r["curve"]]
        ax.plot(steps, success, "o-", color=colour, label=f"{name}: evaluations")
        with open(folder_of(folder, name + suffix) / "episodes.csv") as f:
            rows = list(csv.DictReader(f))
        if len(rows) < 20:  # too few episodes for a running mean of 20 (a short run)
            continue
        won = np.convolve([r["success"] == "1" for r in rows], np.ones(20) / 20, mode="valid")
        done = [float(r["step"]) for r in rows][19:]
        ax.plot(done, 100 * won, color=colour, lw=0.8, alpha=0.6, label=f"{name}: last 20 episodes")
    ax.axhline(100 * threshold, color="0.5", lw=0.8, ls="--")
    ax.set_xlabel("environment steps")
    ax.set_ylabel("success (%)")
    ax.set_title("Gripper, RecurrentPPO (LSTM 128)")
    ax.legend(fontsize=8)
    fig.tight_layout()
    save_figure(fig, path, dpi=110)
    plt.close(fig)


def evaluate_kept(folder: Path, args) -> None:
    """--evaluate: the kept final policies in `folder`, as the runs' final evaluations."""
    runs = {}
    for name in ("bc", "scratch"):
        evaluation = evaluate_saved(
            folder / f"policy_{name}.npz", episodes=args.eval_episodes, seed=EVAL_SEED
        )
        runs[name] = {"training": {"final_evaluation": evaluation.to_dict()}}
    out = args.out or RESULTS
    out.mkdir(parents=True, exist_ok=True)
    (out / "summary.json").write_text(json.dumps({"runs": runs}, indent=1))
    print(json.dumps({name: r["training"]["final_evaluation"] for name, r in runs.items()}))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=60_000)
    parser.add_argument("--eval-freq", type=int, default=10_000)
    parser.add_argument("--eval-episodes", type=int, default=10)
    parser.add_argument("--threshold", type=float, default=0.8)
    parser.add_argument("--bc-epochs", type=int, default=3000)
    parser.add_argument("--expert-episodes", type=int, default=30, help="to clone from")
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--runs", type=Path, default=Path("runs"))
    parser.add_argument(
        "--out", type=Path, default=None, help="results (default: experiments/results/rl/...)"
    )
    parser.add_argument(
        "--only", choices=("bc", "scratch"), default=None, help="run one of the two"
    )
    parser.add_argument("--push-down", action="store_true", help="random downward force")
    parser.add_argument("--sofagym-reward", action="store_true", help="SofaGym's reward")
    parser.add_argument(
        "--evaluate", type=Path, default=None, help="re-evaluate the kept policies here, exit"
    )
    args = parser.parse_args()
    configure_threads(torch_threads=args.threads)
    if args.evaluate is not None:
        if args.out is None:
            parser.error("--evaluate needs --out (not to overwrite the committed results)")
        evaluate_kept(args.evaluate, args)
        return
    results = results_of(args)
    results.mkdir(parents=True, exist_ok=True)
    summary_path = results / "summary.json"
    summary = json.loads(summary_path.read_text()) if summary_path.exists() else {"runs": {}}
    for name, bc in (("bc", True), ("scratch", False)):
        if args.only in (None, name):
            summary["runs"][name] = run(name, bc, args)
            summary_path.write_text(json.dumps(summary, indent=1))
    summary |= {
        "threshold": args.threshold,
        "thesis": THESIS,
        "command": f"PYTHONPATH=. python experiments/rl/gripper_bc.py --steps {args.steps}"
        + " --push-down" * args.push_down
        + " --sofagym-reward" * args.sofagym_reward,
        "cube_push_down": args.push_down,
        "reward": "sofagym" if args.sofagym_reward else "thesis",
    }
    summary_path.write_text(json.dumps(summary, indent=1))
    suffix = variant(args)
    plot(summary["runs"], args.runs, args.threshold, results / "success.png", suffix)
    for name in summary["runs"]:  # kept, and one evaluation episode of each, as a GIF
        export_run(folder_of(args.runs, name + suffix) / "final", results / f"policy_{name}.npz")
        evaluate_saved(
            folder_of(args.runs, name + suffix) / "final",
            episodes=1,
            gif=results / f"{name}.gif",
        )
    print(
        json.dumps(
            {
                name: [r["steps_to_threshold"], r["training_steps_to_threshold"]]
                for name, r in summary["runs"].items()
            }
        )
    )


if __name__ == "__main__":
    main()
