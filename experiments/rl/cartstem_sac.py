"""CartStemContact by SAC (thesis §3.3.2: MLP 3 x 512, solved after 2e5 steps).

    PYTHONPATH=. python experiments/rl/cartstem_sac.py            # start, or resume if begun
    PYTHONPATH=. python experiments/rl/cartstem_sac.py --steps 200000

With ``--stop-at 0.9``, each evaluation (20 goals) of this session that reaches 0.9 is checked
on the final evaluation's 100 goals, and the run stops when those reach 0.9 too. Checkpoints
every 5000 steps in runs/cartstem_sac (not committed); a run stopped at any time resumes
exactly from its latest checkpoint with the same command. The results (learning curve,
evaluations, a GIF, summary.json with the final 100-goal evaluation) are copied to
experiments/results/rl/cartstem_sac/.
"""

from __future__ import annotations

import argparse
import json
import shutil
import time
from pathlib import Path

from stable_baselines3.common.callbacks import BaseCallback

from pliant import configure_threads
from pliant.files import write_json
from pliant.learn import load_config, train
from pliant.learn.evaluate import evaluate_saved, export_run, run_episodes
from pliant.learn.plots import plot_learning_curve
from pliant.learn.vec import make_env

RESULTS = Path("experiments/results/rl/cartstem_sac")
# Disjoint goal draws (each episode k of a draw resets with seed + k).
VALIDATION_SEED = 30_000  # --stop-at's checks
TEST_SEED = 20_000  # the reported figures; chosen by nothing
PROTOCOL = {
    "evaluations_seed": 10_000,  # the 20-goal evaluations, which choose the best policy
    "validation_seed": VALIDATION_SEED,
    "test_seed": TEST_SEED,
    "best": "the policy of the best 20-goal evaluation (success, then return)",
}


class StopAtSuccess(BaseCallback):
    """At each evaluation written in this session (the learning curve in ``evaluations.json``)
    whose success rate reaches `threshold`, the policy is evaluated on `episodes` validation
    goals (seed 30 000 on, logged to ``stop_checks.json``; not the test goals); training stops
    when that success rate reaches `threshold` too (a 20-goal evaluation at 0.9 can be luck: the
    first one that did gave 0.67 on 100 goals)."""

    def __init__(self, run: Path, threshold: float, episodes: int) -> None:
        super().__init__()
        self.path = run / "evaluations.json"
        self.checks = run / "stop_checks.json"
        self.threshold, self.episodes = threshold, episodes
        self.seen = len(json.loads(self.path.read_text())) if self.path.exists() else 0
        self.mtime = self.path.stat().st_mtime if self.path.exists() else 0.0

    def _on_step(self) -> bool:
        if not self.path.exists() or self.path.stat().st_mtime == self.mtime:
            return True
        self.mtime = self.path.stat().st_mtime
        curve = json.loads(self.path.read_text())
        latest = curve[-1]
        if len(curve) <= self.seen or (latest.get("success_rate") or 0.0) < self.threshold:
            return True
        env = make_env("pliant/CartStemContact-v0", {})
        result = run_episodes(self.model, env, self.episodes, seed=VALIDATION_SEED)
        env.close()
        checks = json.loads(self.checks.read_text()) if self.checks.exists() else []
        checks.append({"step": latest["step"], **result.to_dict()})
        self.checks.write_text(json.dumps(checks, indent=1))
        print(
            f"step {latest['step']}: {self.episodes} validation goals {result.success_rate:.2f}",
            flush=True,
        )
        return result.success_rate < self.threshold


def publish(run: Path, partial: bool, command: str) -> None:
    RESULTS.mkdir(parents=True, exist_ok=True)
    for name in ("evaluations.json", "summary.json", "eval.gif", "config.yaml", "stop_checks.json"):
        if (run / name).exists():
            shutil.copy(run / name, RESULTS / name)
    if (run / "evaluations.json").exists():
        title = "CartStemContact, SAC 3x512" + (" (partial run)" if partial else "")
        plot_learning_curve(run, RESULTS / "learning_curve.png", title=title)
    status = {"partial": partial, "resume_command": command}
    (RESULTS / "status.json").write_text(json.dumps(status, indent=1))


def on_test_goals(policy: Path, episodes: int, mode: str):
    """`policy` (a run's folder or a kept policy.npz) on the `episodes` test goals, acting by
    its mean action or by sampling; the samples drawn after seeding torch with the test seed,
    so that the saved model and its kept actor draw the same actions (pliant.learn.kept)."""
    return evaluate_saved(
        policy,
        episodes=episodes,
        seed=TEST_SEED,
        deterministic=mode == "deterministic",
        action_seed=TEST_SEED,
    )


def goal_evaluations(run: Path, episodes: int, last: Path | None = None) -> dict:
    """The final and the best (by the 20-goal evaluations) policies on the same `episodes`
    test goals and carts (seed 20 000 on), acting deterministically (the mean action) and by
    sampling (SAC's policy as it trains: an episode ends at the first step within 1 mm, which a
    sampled action's jitter reaches more often). `last`: the policy to report as the last one
    (default the run's final policy; a stopped run's latest checkpoint)."""
    results = {}
    for name, folder in (("best", run / "best"), ("last", last or run / "final")):
        if not folder.exists():
            continue
        step = {}
        if name == "best":  # saved at the evaluation with the best score (EvalCallback)
            curve = json.loads((run / "evaluations.json").read_text())
            best = max(curve, key=lambda e: (e["success_rate"] or 0.0) + 1e-9 * e["mean_return"])
            step = {"step": best["step"]}
        for mode in ("deterministic", "stochastic"):
            evaluation = on_test_goals(folder, episodes, mode)
            results[f"{name}_{mode}"] = {**step, **evaluation.to_dict()}
    return results


def publish_partial(run: Path, episodes: int, command: str) -> None:
    """A stopped run: its latest checkpoint's policy evaluated on `episodes` goals, a GIF,
    the learning curve so far, all labelled partial; the best policy's goals as well (chosen
    on the 20-goal evaluations, seed 10 000 on), and that policy kept (policy.npz)."""
    import pickle

    from pliant.learn.callbacks import latest_checkpoint

    checkpoint = latest_checkpoint(run)
    with open(checkpoint / "state.pkl", "rb") as f:
        state = pickle.load(f)
    evaluation = evaluate_saved(
        checkpoint, episodes=episodes, seed=TEST_SEED, gif=run / "eval.gif", gif_episodes=2
    )
    summary = {
        "partial": True,
        "env_id": "pliant/CartStemContact-v0",
        "algo": "SAC, MLP 3x512",
        "steps": state["num_timesteps"],
        "wall_seconds": state["counters"]["wall_seconds"],
        "diverged_episodes": state["counters"]["diverged"],
        f"evaluation_{episodes}_goals": evaluation.to_dict(),
        f"{episodes}_goals": goal_evaluations(run, episodes, last=checkpoint),
        "stop_checks": (
            json.loads((run / "stop_checks.json").read_text())
            if (run / "stop_checks.json").exists()
            else []
        ),
        "thesis": {"algo": "SAC, MLP 3x512", "steps_to_solve": 200_000},
        "protocol": PROTOCOL,
    }
    (run / "summary.json").write_text(json.dumps(summary, indent=1))
    publish(run, partial=True, command=command)
    if (run / "best").exists():  # the policy its figures report, chosen on validation goals
        export_run(run / "best", RESULTS / "policy.npz")


def evaluate_kept(policy: Path, episodes: int, out: Path) -> None:
    """A kept policy on the `episodes` test goals, both ways of acting (--evaluate)."""
    results = {}
    for mode in ("deterministic", "stochastic"):
        results[f"best_{mode}"] = on_test_goals(policy, episodes, mode).to_dict()
    out.mkdir(parents=True, exist_ok=True)
    write_json(out / "summary.json", {"policy": str(policy), f"{episodes}_goals": results})
    print(json.dumps(results, indent=1))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--steps", type=int, default=200_000)
    parser.add_argument("--n-envs", type=int, default=2)
    parser.add_argument("--final-episodes", type=int, default=100)
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--eval-episodes", type=int, default=20)
    parser.add_argument(
        "--stop-at",
        type=float,
        default=None,
        help="stop at the first evaluation of this session with this success rate",
    )
    parser.add_argument("--run", type=Path, default=Path("runs/cartstem_sac"))
    parser.add_argument(
        "--publish-partial",
        action="store_true",
        help="copy the results so far of a stopped run, labelled partial, and exit",
    )
    parser.add_argument(
        "--evaluate",
        type=Path,
        help="re-evaluate a kept policy (.npz) on the test goals into --results, and exit",
    )
    parser.add_argument("--results", type=Path, help="where --evaluate writes summary.json")
    args = parser.parse_args()
    if args.evaluate is not None:
        if args.results is None:
            parser.error("--evaluate needs --results")
        evaluate_kept(args.evaluate, args.final_episodes, args.results)
        return
    RUN = args.run
    configure_threads(torch_threads=args.threads)
    command = f"PYTHONPATH=. python experiments/rl/cartstem_sac.py --steps {args.steps}"
    if args.stop_at is not None:
        command += f" --stop-at {args.stop_at}"
    if args.publish_partial:
        publish_partial(RUN, args.final_episodes, command)
        return
    resume = (RUN / "checkpoints").exists() and any((RUN / "checkpoints").glob("step_*"))
    config = load_config(
        "pliant/CartStemContact-v0",
        "SAC",
        overrides={
            "total_timesteps": args.steps,
            "n_envs": args.n_envs,
            "eval_episodes": args.eval_episodes,
        },
    )
    clock = time.perf_counter()
    stop = [] if args.stop_at is None else [StopAtSuccess(RUN, args.stop_at, args.final_episodes)]
    result = train(config, RUN, resume=resume, total_timesteps=args.steps, extra_callbacks=stop)
    if result.summary["stopped_by"] is not None:  # a signal: checkpointed, rerun to go on
        print(f"stopped by {result.summary['stopped_by']} at step {result.summary['steps']}")
        return
    final = evaluate_saved(RUN / "final", episodes=args.final_episodes, seed=TEST_SEED)
    summary = {
        **result.summary,
        "final_100_goals": final.to_dict(),
        f"{args.final_episodes}_goals": goal_evaluations(RUN, args.final_episodes),
        "wall_seconds_with_final_evaluation_this_session": time.perf_counter() - clock,
        "thesis": {"algo": "SAC, MLP 3x512", "steps_to_solve": 200_000},
        "protocol": PROTOCOL,
    }
    (RUN / "summary.json").write_text(json.dumps(summary, indent=1))
    publish(RUN, partial=False, command=command)
    # The reported policy, kept (the actor alone), for --evaluate.
    export_run(RUN / "best" if (RUN / "best").exists() else RUN / "final", RESULTS / "policy.npz")


if __name__ == "__main__":
    main()
