"""Kill-and-resume counts (issue 64): training runs killed with SIGKILL at a random time, resumed
with ``--resume``, compared bit for bit with an uninterrupted run.

One run type, SB3 training: PPO on the toy ``pliant-test/PointReach-v0`` (VecNormalize on, one
environment in the learner's process, a checkpoint every ``--checkpoint`` steps, one PyTorch
thread). Each run is a fresh process (``train(config, run)``); it is killed (SIGKILL) at a time
drawn uniformly over the first 90 % of the reference run's training time (seeded: ``--seed``
and the run's index), then a fresh process resumes it (``train(run_dir=run, resume=True)``,
what ``pliant train --resume`` calls). A run killed before its first checkpoint has nothing to
resume from and is started again, as a user would (counted apart). The final policy parameters and
VecNormalize statistics are compared with the uninterrupted reference run's, bit for bit.

The study resumes itself: the results are written (atomically) after each run, and a rerun of
the same command goes on from the first missing run. From the repository root::

    python experiments/reliability/kill_resume.py --runs 25

writes ``experiments/results/reliability/kill_resume_sb3.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
RESULTS = ROOT / "experiments" / "results" / "reliability" / "kill_resume_sb3.json"
#: One thread everywhere: PyTorch's reductions, hence the last bits, depend on the count.
CHILD_ENV = {
    **os.environ,
    "PYTHONPATH": str(ROOT),
    "OMP_NUM_THREADS": "1",
    "MKL_NUM_THREADS": "1",
    "NUMBA_NUM_THREADS": "1",
}


def training_config(steps: int, checkpoint: int) -> dict:
    return dict(
        env_id="pliant-test/PointReach-v0",
        algo="PPO",
        total_timesteps=steps,
        n_envs=1,
        vec_env="dummy",
        eval_freq=0,
        eval_episodes=0,
        checkpoint_freq=checkpoint,
        keep_checkpoints=2,
        video_episodes=0,
        normalize=True,
        seed=7,
        hyperparams={"policy": "MlpPolicy", "n_steps": 64, "batch_size": 32, "n_epochs": 4},
    )


# ----------------------------------------------------------------------------- child process
def child(action: str, run_dir: str, out: str, config_json: str) -> None:
    """`action` "train": a run from the start; "resume": from its newest intact checkpoint (from
    the start when it has none). The final parameters and statistics go to `out` (.npz)."""
    import warnings

    import torch
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.vec_env import VecNormalize

    from pliant.files import save_npz
    from pliant.learn import TrainConfig, parameters, train

    warnings.simplefilter("ignore")
    torch.set_num_threads(1)

    class Started(BaseCallback):
        def _on_training_start(self) -> None:
            print("started", flush=True)

        def _on_step(self) -> bool:
            return True

    config = TrainConfig(**json.loads(config_json))
    resumed_from = None
    if action == "resume" and any(Path(run_dir, "checkpoints").glob("step_*")):
        result = train(run_dir=run_dir, resume=True)
        resumed_from = result.summary["resumed_from"]
    else:
        result = train(config, run_dir, extra_callbacks=[Started()])
    arrays = {f"policy/{k}": v for k, v in parameters(result.model).items()}
    venv = result.model.get_env()
    if isinstance(venv, VecNormalize):
        for name in ("obs_rms", "ret_rms"):
            rms = getattr(venv, name)
            arrays[f"{name}/mean"] = np.asarray(rms.mean)
            arrays[f"{name}/var"] = np.asarray(rms.var)
            arrays[f"{name}/count"] = np.asarray(rms.count)
    save_npz(out, **arrays)
    print("resumed_from", resumed_from, flush=True)


def _spawn(action: str, run_dir: Path, out: Path, config: dict) -> subprocess.Popen:
    """A child process; its stderr goes to ``<run_dir>.<action>.log`` (a pipe left unread
    could fill and stop it)."""
    args = [sys.executable, __file__, "_child", action, str(run_dir), str(out), json.dumps(config)]
    with open(f"{run_dir}.{action}.log", "w") as log:
        return subprocess.Popen(
            args, cwd=ROOT, env=CHILD_ENV, stdout=subprocess.PIPE, stderr=log, text=True
        )


def _finish(process: subprocess.Popen, what: str) -> str:
    out, _ = process.communicate(timeout=1800)
    if process.returncode != 0:
        log = Path(process.args[3] + f".{process.args[2]}.log").read_text()
        raise RuntimeError(f"{what} failed ({process.returncode}):\n{log[-3000:]}")
    return out


# ---------------------------------------------------------------------------------- study
def reference(work: Path, config: dict) -> tuple[Path, float]:
    """The uninterrupted run: its parameters and its training time (from "started" to exit)."""
    out = work / "reference.npz"
    shutil.rmtree(work / "reference", ignore_errors=True)
    process = _spawn("train", work / "reference", out, config)
    assert process.stdout.readline().strip() == "started"
    start = time.perf_counter()
    _finish(process, "the reference run")
    return out, time.perf_counter() - start


def compare(a: Path, b: Path) -> dict:
    """Bit for bit: the same arrays, dtypes, shapes and bytes; and the largest difference."""
    from pliant.files import load_npz

    x, y = load_npz(a, "parameters"), load_npz(b, "parameters")
    if set(x) != set(y):
        return {"identical": False, "max_abs_difference": None}
    same, worst = True, 0.0
    for key, u in x.items():
        v = y[key]
        same &= u.dtype == v.dtype and u.shape == v.shape and u.tobytes() == v.tobytes()
        worst = max(worst, float(np.max(np.abs(u.astype(float) - v.astype(float)))))
    return {"identical": bool(same), "max_abs_difference": worst}


def kill_and_resume(work: Path, index: int, seed: int, config: dict, window: float) -> dict:
    run_dir, out = work / f"run_{index:03d}", work / f"run_{index:03d}.npz"
    shutil.rmtree(run_dir, ignore_errors=True)
    out.unlink(missing_ok=True)
    kill_after = float(np.random.default_rng([seed, index]).uniform(0.0, window))
    clock = time.perf_counter()
    process = _spawn("train", run_dir, work / "unused.npz", config)
    assert process.stdout.readline().strip() == "started"
    try:
        process.wait(timeout=kill_after)
        killed = False  # it finished first (a loaded machine runs at another speed)
    except subprocess.TimeoutExpired:
        os.kill(process.pid, signal.SIGKILL)
        process.wait()
        killed = True
    process.communicate()
    checkpoints = sorted(int(p.name[5:]) for p in (run_dir / "checkpoints").glob("step_*"))
    resumed = _finish(_spawn("resume", run_dir, out, config), f"resume of run {index}")
    resumed_from = resumed.split()[-1]
    return {
        "run": index,
        "kill_after_s": round(kill_after, 3),
        "killed": killed,
        "checkpoints_at_kill": checkpoints,
        "resumed_from": None if resumed_from == "None" else int(resumed_from),
        **compare(work / "reference.npz", out),
        "seconds": round(time.perf_counter() - clock, 1),
    }


def summarise(runs: list[dict]) -> dict:
    killed = [r for r in runs if r["killed"]]
    resumed = [r for r in killed if r["resumed_from"] is not None]
    return {
        "runs": len(runs),
        "killed": len(killed),
        "resumed_from_a_checkpoint": len(resumed),
        "restarted_no_checkpoint_yet": len(killed) - len(resumed),
        "identical": sum(r["identical"] for r in runs),
        "identical_among_resumed": sum(r["identical"] for r in resumed),
        "share_identical": sum(r["identical"] for r in runs) / max(len(runs), 1),
        "seconds_per_run": round(float(np.mean([r["seconds"] for r in runs])), 1) if runs else 0,
    }


def main() -> None:
    from pliant.files import write_json

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=25)
    parser.add_argument("--steps", type=int, default=6000, help="training steps of a run")
    parser.add_argument("--checkpoint", type=int, default=640, help="steps between checkpoints")
    parser.add_argument("--seed", type=int, default=0, help="seed of the kill times")
    parser.add_argument("--work", type=Path, default=ROOT / "runs" / "kill_resume_sb3")
    parser.add_argument("--out", type=Path, default=RESULTS)
    args = parser.parse_args()

    config = training_config(args.steps, args.checkpoint)
    setup = {"config": config, "seed": args.seed, "runs_asked": args.runs}
    report = json.loads(args.out.read_text()) if args.out.exists() else {}
    if report.get("setup") != setup or not (args.work / "reference.npz").exists():
        args.work.mkdir(parents=True, exist_ok=True)
        _, seconds = reference(args.work, config)
        report = {"setup": setup, "reference_training_s": round(seconds, 2), "results": []}
        write_json(args.out, report)
        print(f"reference run: {seconds:.1f} s of training", flush=True)
    window = 0.9 * report["reference_training_s"]  # a run may go faster than the reference
    runs = report["results"]
    for index in range(len(runs), args.runs):
        runs.append(kill_and_resume(args.work, index, args.seed, config, window))
        report["summary"] = summarise(runs)
        write_json(args.out, report)
        print(json.dumps(runs[-1]), flush=True)
    print(json.dumps(report["summary"], indent=1))


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == "_child":
        child(*sys.argv[2:6])
    else:
        main()
