"""Kill-and-resume counts (issue 64): long runs killed with SIGKILL at a random time, resumed,
and compared bit for bit with an uninterrupted run.

Two run types (``--kind``):

- ``sb3``, SB3 training: PPO on the toy ``pliant-test/PointReach-v0`` (VecNormalize on, one
  environment in the learner's process, a checkpoint every ``--checkpoint`` steps, one PyTorch
  thread). Each run is a fresh process (``train(config, run)``), killed at a time drawn
  uniformly over the first 90 % of the reference run's training time (from the first step);
  then a fresh process resumes it (``train(run_dir=run, resume=True)``, what ``pliant train
  --resume`` calls). A run killed before its first checkpoint has nothing to resume from and
  is started again, as a user would (counted apart). Compared: the final policy parameters and
  VecNormalize statistics.
- ``collect``, condensed data collection: ``pliant condensed collect finger`` (one process,
  ``--chunk`` samples a chunk), killed at a time drawn uniformly over the first 90 % of the
  reference command's solving time (from the moment its chunk folder appears, after imports
  and meshing), then the same command again (what resumes a collection). Compared: every
  field of both splits.

Kill times are seeded (``--seed`` and the run's index). The study resumes itself: the results
are written (atomically) after each run, and the same command goes on from the first missing
run. From the repository root::

    python experiments/reliability/kill_resume.py --kind sb3 --runs 25
    python experiments/reliability/kill_resume.py --kind collect --runs 25 --samples 80

(``--runs`` larger than the results hold adds runs to them; other settings start afresh.)

write ``experiments/results/reliability/kill_resume_<kind>.json``.
"""

from __future__ import annotations

import argparse
import dataclasses
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
#: One thread everywhere: PyTorch's reductions, hence the last bits, depend on the count.
CHILD_ENV = {
    **os.environ,
    "PYTHONPATH": str(ROOT),
    "OMP_NUM_THREADS": "1",
    "MKL_NUM_THREADS": "1",
    "NUMBA_NUM_THREADS": "1",
}


def _same_arrays(x: dict, y: dict) -> dict:
    """Bit for bit: the same names, dtypes, shapes and bytes; and the largest difference."""
    if set(x) != set(y):
        return {"identical": False, "max_abs_difference": None}
    same, worst = True, 0.0
    for key, u in x.items():
        v = y[key]
        same &= u.dtype == v.dtype and u.shape == v.shape and u.tobytes() == v.tobytes()
        if u.shape == v.shape and u.size:
            worst = max(worst, float(np.max(np.abs(u.astype(float) - v.astype(float)))))
    return {"identical": bool(same), "max_abs_difference": worst}


def _log(work: Path, label: str, action: str):
    """Where a child's output goes (a pipe left unread could fill and stop it)."""
    return open(work / f"{label}.{action}.log", "w")


def _finish(process: subprocess.Popen, what: str, log: Path) -> str:
    out, _ = process.communicate(timeout=1800)
    if process.returncode != 0:
        raise RuntimeError(f"{what} failed ({process.returncode}):\n{log.read_text()[-3000:]}")
    return out or ""


# --------------------------------------------------------------------------- SB3 training
class Training:
    kind = "sb3"
    result = ".npz"  # what a run leaves: <label>.npz

    def __init__(self, args: argparse.Namespace) -> None:
        self.config = dict(
            env_id="pliant-test/PointReach-v0",
            algo="PPO",
            total_timesteps=args.steps,
            n_envs=1,
            vec_env="dummy",
            eval_freq=0,
            eval_episodes=0,
            checkpoint_freq=args.checkpoint,
            keep_checkpoints=2,
            video_episodes=0,
            normalize=True,
            seed=7,
            hyperparams={"policy": "MlpPolicy", "n_steps": 64, "batch_size": 32, "n_epochs": 4},
        )

    def setup(self) -> dict:
        return {"config": self.config}

    def _spawn(self, work: Path, label: str, action: str) -> subprocess.Popen:
        args = [sys.executable, __file__, "_child", action, str(work / label)]
        with _log(work, label, action) as log:
            return subprocess.Popen(
                [*args, json.dumps(self.config)],
                cwd=ROOT,
                env=CHILD_ENV,
                stdout=subprocess.PIPE,
                stderr=log,
                text=True,
            )

    def start(self, work: Path, label: str) -> subprocess.Popen:
        """A fresh run, returned at its first step."""
        shutil.rmtree(work / label, ignore_errors=True)
        Path(f"{work / label}.npz").unlink(missing_ok=True)
        process = self._spawn(work, label, "train")
        assert process.stdout.readline().strip() == "started"
        return process

    def finish(self, process: subprocess.Popen, work: Path, label: str) -> None:
        _finish(process, f"run {label}", work / f"{label}.train.log")

    def progress(self, work: Path, label: str) -> dict:
        steps = sorted(int(p.name[5:]) for p in (work / label / "checkpoints").glob("step_*"))
        return {"checkpoints_at_kill": steps}

    def resume(self, work: Path, label: str) -> dict:
        process = self._spawn(work, label, "resume")
        out = _finish(process, f"resume of {label}", work / f"{label}.resume.log")
        resumed_from = out.split()[-1]
        return {"resumed_from": None if resumed_from == "None" else int(resumed_from)}

    def compare(self, work: Path, label: str) -> dict:
        from pliant.files import load_npz

        reference = load_npz(work / "reference.npz", "parameters")
        return _same_arrays(reference, load_npz(work / f"{label}.npz", "parameters"))


def child(action: str, run_dir: str, config_json: str) -> None:
    """`action` "train": a run from the start; "resume": from its newest intact checkpoint
    (from the start when it has none). The final parameters and statistics go to
    ``<run_dir>.npz``."""
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
    save_npz(f"{run_dir}.npz", **arrays)
    print("resumed_from", resumed_from, flush=True)


# ------------------------------------------------------------------ condensed collection
class Collection:
    kind = "collect"
    result = ".h5"

    def __init__(self, args: argparse.Namespace) -> None:
        self.options = [
            "finger",
            *("--bounds", "0:4", "--samples", str(args.samples), "--seed", "3"),
            *("--chunk-size", str(args.chunk), "--workers", "1"),
        ]

    def setup(self) -> dict:
        return {"command": ["pliant", "condensed", "collect", *self.options]}

    def start(self, work: Path, label: str) -> subprocess.Popen:
        """A fresh collection, returned when it starts solving (its chunk folder is made)."""
        out = work / f"{label}.h5"
        parts = out.with_name(out.name + ".parts")
        out.unlink(missing_ok=True)
        shutil.rmtree(parts, ignore_errors=True)
        process = self._spawn(work, label, "collect")
        while not parts.exists() and process.poll() is None:
            time.sleep(0.02)
        return process

    def _spawn(self, work: Path, label: str, action: str) -> subprocess.Popen:
        command = ["condensed", "collect", *self.options, "--out", str(work / f"{label}.h5")]
        with _log(work, label, action) as log:
            return subprocess.Popen(
                [sys.executable, "-m", "pliant.cli", *command],
                cwd=ROOT,
                env=CHILD_ENV,
                stdout=log,
                stderr=subprocess.STDOUT,
            )

    def finish(self, process: subprocess.Popen, work: Path, label: str) -> None:
        _finish(process, f"collection {label}", work / f"{label}.collect.log")

    def progress(self, work: Path, label: str) -> dict:
        parts = work / f"{label}.h5.parts"
        chunks = [p for p in parts.glob("*") if p.is_file()] if parts.is_dir() else []
        return {"chunks_at_kill": len(chunks), "dataset_at_kill": (work / f"{label}.h5").exists()}

    def resume(self, work: Path, label: str) -> dict:
        if (work / f"{label}.h5").exists():  # written before the kill: nothing to resume
            return {"resumed": False}
        process = self._spawn(work, label, "resume")
        _finish(process, f"resume of {label}", work / f"{label}.resume.log")
        return {"resumed": True}

    def compare(self, work: Path, label: str) -> dict:
        from pliant.condensed.dataset import Dataset, Split

        def arrays(path: Path) -> dict:
            dataset = Dataset.load(path)
            return {
                f"{name}/{f.name}": np.asarray(getattr(dataset.split(name), f.name))
                for name in ("train", "test")
                for f in dataclasses.fields(Split)
            }

        return _same_arrays(arrays(work / "reference.h5"), arrays(work / f"{label}.h5"))


# ---------------------------------------------------------------------------------- study
def reference(kind, work: Path) -> float:
    """The uninterrupted run; returns its time from `kind.start`'s return to its end."""
    process = kind.start(work, "reference")
    clock = time.perf_counter()
    kind.finish(process, work, "reference")
    return time.perf_counter() - clock


def kill_and_resume(kind, work: Path, index: int, seed: int, window: float) -> dict:
    label = f"run_{index:03d}"
    kill_after = float(np.random.default_rng([seed, index]).uniform(0.0, window))
    clock = time.perf_counter()
    process = kind.start(work, label)
    try:
        process.wait(timeout=kill_after)
        killed = False  # it finished first (a loaded machine runs at another speed)
    except subprocess.TimeoutExpired:
        os.kill(process.pid, signal.SIGKILL)
        killed = True
    process.communicate()
    progress = kind.progress(work, label)
    return {
        "run": index,
        "kill_after_s": round(kill_after, 3),
        "killed": killed,
        **progress,
        **kind.resume(work, label),
        **kind.compare(work, label),
        "seconds": round(time.perf_counter() - clock, 1),
    }


def summarise(runs: list[dict]) -> dict:
    killed = [r for r in runs if r["killed"]]
    # Killed with saved progress to resume from: a checkpoint, or chunks of the collection.
    saved = [r for r in killed if r.get("resumed_from") is not None or r.get("chunks_at_kill")]
    return {
        "runs": len(runs),
        "killed": len(killed),
        "killed_with_saved_progress": len(saved),
        "identical": sum(r["identical"] for r in runs),
        "identical_among_killed": sum(r["identical"] for r in killed),
        "identical_among_killed_with_saved_progress": sum(r["identical"] for r in saved),
        "share_identical": sum(r["identical"] for r in runs) / max(len(runs), 1),
        "seconds_per_run": round(float(np.mean([r["seconds"] for r in runs])), 1) if runs else 0,
    }


def main() -> None:
    from pliant.files import write_json

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--kind", choices=("sb3", "collect"), default="sb3")
    parser.add_argument("--runs", type=int, default=25)
    parser.add_argument("--seed", type=int, default=0, help="seed of the kill times")
    parser.add_argument("--steps", type=int, default=6000, help="sb3: training steps of a run")
    parser.add_argument("--checkpoint", type=int, default=640, help="sb3: steps a checkpoint")
    parser.add_argument("--samples", type=int, default=80, help="collect: training samples")
    parser.add_argument("--chunk", type=int, default=2, help="collect: samples a chunk")
    parser.add_argument("--work", type=Path, help="default: runs/kill_resume_<kind>")
    parser.add_argument("--out", type=Path, help="default: experiments/results/reliability/")
    args = parser.parse_args()

    kind = {"sb3": Training, "collect": Collection}[args.kind](args)
    work = args.work or ROOT / "runs" / f"kill_resume_{args.kind}"
    out = (
        args.out
        or ROOT / "experiments" / "results" / "reliability" / f"kill_resume_{args.kind}.json"
    )
    setup = {**kind.setup(), "seed": args.seed}
    report = json.loads(out.read_text()) if out.exists() else {}
    if report.get("setup") != setup or not (work / f"reference{kind.result}").exists():
        work.mkdir(parents=True, exist_ok=True)
        seconds = reference(kind, work)
        report = {"setup": setup, "reference_s": round(seconds, 2), "results": []}
        write_json(out, report)
        print(f"reference run: {seconds:.1f} s", flush=True)
    window = 0.9 * report["reference_s"]  # a run may go faster than the reference
    runs = report["results"]
    for index in range(len(runs), args.runs):
        runs.append(kill_and_resume(kind, work, index, args.seed, window))
        report["summary"] = summarise(runs)
        write_json(out, report)
        print(json.dumps(runs[-1]), flush=True)
    print(json.dumps(report["summary"], indent=1))


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == "_child":
        child(*sys.argv[2:5])
    else:
        main()
