"""Kill-and-resume counts (issue 64): long runs killed with SIGKILL at a random time, resumed,
and compared bit for bit with an uninterrupted run.

Five run types (``--kind``):

- ``sb3``, SB3 training: PPO on the toy ``pliant-test/PointReach-v0`` (VecNormalize on, one
  environment in the learner's process, a checkpoint every ``--checkpoint`` steps, one PyTorch
  thread). Each run is a fresh process (``train(config, run)``), killed at a kill time
  counted from its first step; then a fresh process resumes it (``train(run_dir=run,
  resume=True)``, what ``pliant train --resume`` calls). A run killed before its first
  checkpoint has nothing to resume from and is started again, as a user would (counted
  apart). Compared: the final policy parameters and VecNormalize statistics.
- ``collect``, condensed data collection: ``pliant condensed collect finger`` (one process,
  ``--chunk`` samples a chunk), killed at a kill time counted from the moment its chunk
  folder appears (after imports and meshing), then the same command again (what resumes a
  collection). Compared: every field of both splits.
- ``reduce``, reduction snapshots: :func:`pliant.reduction.snapshots.collect` of the Finger
  (``--cases`` load cases, each pulling both cables for 0.4 s, a record every 2 steps, in
  this process, as ``pliant reduce`` collects them), started in a fresh process and killed
  at a kill time counted from the moment the model is built, then the same call again.
  Compared: every dataset and attribute of the HDF5 file.
- ``calibrate``, proxy calibration: ``pliant proxy calibrate multigait --trials N`` on a
  reference trajectory made once by the Multigait's proxy itself (20 steps; its study in
  SQLite), killed at a kill time counted from the moment its study file appears, then the
  same command again. Compared: every finished trial (number among the finished,
  parameters, value) and the report's parameters and errors.
- ``graph``, graph training: ``pliant graph train Corridor`` (the toy corridor of three
  contact configurations, small networks, an evaluation and checkpoint every
  ``--eval-every`` steps), killed at a kill time counted from the moment its TensorBoard
  folder appears, then the same command again (it resumes by default). Compared: every
  array and number of the final checkpoint (networks,
  optimisers, replay buffers, generators, counters) and the evaluations (their wall times
  left out).

Kill times: each command is a batch; it first runs the work uninterrupted twice (a warm-up
that compiles numba's kernels, then a timed run: the reference, from the same moment a run's
kill time counts from to its end), on this machine under its load of the moment, and draws
each run's kill time uniformly over that measured time (seeded by ``--seed`` and the run's
index). A run that ends before its kill time (the load changed) is not killed: it is
reported (``killed: false``, with ``ended_after_s``) and counted apart; ``--killed N`` stops
once N runs were killed; ``--batch-runs N`` starts a new batch (its reference timed again,
without the warm-up) every N runs, so that the window follows the machine's load. The study
resumes itself: the results are written (atomically) after each run, and the same command
goes on from the first missing run. From the repository root::

    python experiments/reliability/kill_resume.py --kind sb3 --runs 25
    python experiments/reliability/kill_resume.py --kind collect --runs 25 --samples 80
    python experiments/reliability/kill_resume.py --kind reduce --runs 30 --killed 20
    python experiments/reliability/kill_resume.py --kind calibrate --runs 50 --killed 44 \
        --batch-runs 5
    python experiments/reliability/kill_resume.py --kind graph --runs 45 --killed 20 --batch-runs 5

(``--runs`` larger than the results hold adds runs to them, in a new batch with its own
reference; other settings start afresh.)

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
        if u.shape == v.shape and u.size and u.dtype.kind in "biuf" and v.dtype.kind in "biuf":
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

    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.vec_env import VecNormalize

    from pliant import configure_threads
    from pliant.files import save_npz
    from pliant.learn import TrainConfig, parameters, train

    warnings.simplefilter("ignore")
    configure_threads(torch_threads=1)

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


# ------------------------------------------------------------------ commands, generically
class Forked:
    """A child process made by the study's fork server, which imported Pliant once: it starts
    in milliseconds rather than the seconds an interpreter takes to import Pliant, numba and
    PyTorch (on a loaded machine, a minute), yet is a process of its own, killed by SIGKILL
    as any, its memory and files nothing of its parent's or siblings'. The interface of
    ``subprocess.Popen`` that the study uses."""

    def __init__(self, argv: list[str], log: Path) -> None:
        self.process = _context().Process(target=_forked_main, args=(argv, str(log)))
        self.process.start()
        self.pid = self.process.pid

    @property
    def returncode(self) -> int | None:
        return self.process.exitcode

    def poll(self) -> int | None:
        return None if self.process.is_alive() else self.process.exitcode

    def wait(self, timeout: float | None = None) -> int:
        self.process.join(timeout)
        if self.process.is_alive():
            raise subprocess.TimeoutExpired("forked child", timeout)
        return self.process.exitcode

    def communicate(self, timeout: float | None = None) -> tuple[str, None]:
        self.wait(timeout)
        return "", None


_CONTEXT = None


def _context():
    """The fork server, started once with Pliant's modules imported (and the children's
    environment: one thread)."""
    global _CONTEXT
    if _CONTEXT is None:
        import multiprocessing

        os.environ.update(CHILD_ENV)
        _CONTEXT = multiprocessing.get_context("forkserver")
        _CONTEXT.set_forkserver_preload(["__main__", "pliant.cli", "torch", "optuna", "h5py"])
    return _CONTEXT


def _forked_main(argv: list[str], log: str) -> None:
    """A forked child: its output to `log`, then ``pliant ARGV`` (argv[0] "cli") or one of
    this file's children."""
    fd = os.open(log, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
    os.dup2(fd, 1)
    os.dup2(fd, 2)
    if argv[0] == "cli":
        from pliant.cli import app

        app(argv[1:], prog_name="pliant")  # ends with SystemExit(status)
    elif argv[0] == "_reduce":
        reduce_child(*argv[1:])


class Command:
    """A run that is one command (a CLI call or this file's child, in a :class:`Forked`
    process), started again to resume; `marker(work, label)` is the path whose appearance
    says that the work has started."""

    kind = ""
    result = ""

    def command(self, work: Path, label: str) -> list[str]:
        raise NotImplementedError

    def marker(self, work: Path, label: str) -> Path:
        raise NotImplementedError

    def clear(self, work: Path, label: str) -> None:
        raise NotImplementedError

    def start(self, work: Path, label: str) -> Forked:
        self.clear(work, label)
        process = self._spawn(work, label, "run")
        marker = self.marker(work, label)
        while not marker.exists() and process.poll() is None:
            time.sleep(0.02)
        return process

    def _spawn(self, work: Path, label: str, action: str) -> Forked:
        return Forked(self.command(work, label), work / f"{label}.{action}.log")

    def finish(self, process: Forked, work: Path, label: str) -> None:
        _finish(process, f"{self.kind} {label}", work / f"{label}.run.log")

    def resume(self, work: Path, label: str) -> dict:
        process = self._spawn(work, label, "resume")
        _finish(process, f"resume of {label}", work / f"{label}.resume.log")
        return {"resumed": True}


def h5_contents(path: Path) -> dict:
    """Every dataset's values and every attribute of an HDF5 file, by name."""
    import h5py

    out = {}
    with h5py.File(path, "r") as f:

        def visit(name, item):
            out.update({f"{name}@{k}": np.asarray(v) for k, v in item.attrs.items()})
            if isinstance(item, h5py.Dataset):
                out[name] = np.asarray(item[()])

        f.visititems(visit)
        out.update({f"@{k}": np.asarray(v) for k, v in f.attrs.items()})
    return out


# ----------------------------------------------------------------- reduction snapshots
class Reduction(Command):
    kind = "reduce"
    result = ".h5"

    def __init__(self, args: argparse.Namespace) -> None:
        self.cases = args.cases

    def setup(self) -> dict:
        return {"call": "pliant.reduction.snapshots.collect", "robot": "finger",
                "cases": self.cases, "duration_s": 0.4, "dt": 0.01, "every": 2}  # fmt: skip

    def command(self, work: Path, label: str) -> list[str]:
        return ["_reduce", str(work / f"{label}.h5"), str(self.cases)]

    def marker(self, work: Path, label: str) -> Path:
        return work / f"{label}.built"

    def clear(self, work: Path, label: str) -> None:
        for suffix in (".h5", ".built"):
            (work / f"{label}{suffix}").unlink(missing_ok=True)
        shutil.rmtree(work / f"{label}.h5.parts", ignore_errors=True)

    def progress(self, work: Path, label: str) -> dict:
        parts = work / f"{label}.h5.parts"
        records = len(list(parts.rglob("*.npz"))) if parts.is_dir() else 0
        finished = 0
        if (work / f"{label}.h5").exists():
            names = {k.split("/")[1].split("@")[0] for k in h5_contents(work / f"{label}.h5")
                     if k.startswith("cases/")}  # fmt: skip
            finished = len(names)
        return {"records_at_kill": records, "cases_finished_at_kill": finished}

    def compare(self, work: Path, label: str) -> dict:
        return _same_arrays(h5_contents(work / "reference.h5"), h5_contents(work / f"{label}.h5"))


def reduce_child(path: str, cases: str) -> None:
    """The Finger's snapshots: `cases` load cases pulling both cables to other levels."""
    from pliant import robots
    from pliant.reduction.pipeline import RampedCommands
    from pliant.reduction.snapshots import LoadCase, collect

    model = robots.entry("finger").build()
    levels = np.linspace(1.0, 5.0, int(cases))
    loads = [
        LoadCase(f"pull_{k}", RampedCommands([np.array([a, 0.5 * a])] * 2, 0.2), 0.4)
        for k, a in enumerate(levels)
    ]
    Path(f"{Path(path).with_suffix('')}.built").touch()
    collect(model, loads, path, dt=0.01, every=2)


# --------------------------------------------------------------------- proxy calibration
class Calibration(Command):
    kind = "calibrate"
    result = "/multigait_calibration.json"

    def __init__(self, args: argparse.Namespace) -> None:
        self.trials = args.trials

    def setup(self) -> dict:
        return {"command": ["pliant", "proxy", "calibrate", "multigait", "--trials",
                            str(self.trials), "--reference", "proxy_reference.npz"]}  # fmt: skip

    def reference_file(self, work: Path) -> Path:
        """The Multigait proxy's own 20 steps (its default parameters): what it is fitted to."""
        path = work / "proxy_reference.npz"
        if not path.exists():
            subprocess.run([sys.executable, __file__, "_proxy_reference", str(path)],
                           cwd=ROOT, env=CHILD_ENV, check=True)  # fmt: skip
        return path

    def command(self, work: Path, label: str) -> list[str]:
        return ["cli", "proxy", "calibrate", "multigait",
                "--trials", str(self.trials), "--reference", str(self.reference_file(work)),
                "--out", str(work / label)]  # fmt: skip

    def marker(self, work: Path, label: str) -> Path:
        return work / label / "multigait.db"

    def clear(self, work: Path, label: str) -> None:
        shutil.rmtree(work / label, ignore_errors=True)

    def progress(self, work: Path, label: str) -> dict:
        return {"trials_at_kill": len(self._trials(work / label)) if
                self.marker(work, label).exists() else 0}  # fmt: skip

    @staticmethod
    def _trials(folder: Path) -> list:
        import optuna

        optuna.logging.set_verbosity(optuna.logging.WARNING)
        try:
            study = optuna.load_study(study_name="multigait",
                                      storage=f"sqlite:///{folder / 'multigait.db'}")  # fmt: skip
        except KeyError:  # killed before the study was made
            return []
        return study.get_trials(states=(optuna.trial.TrialState.COMPLETE,))

    def _arrays(self, folder: Path) -> dict:
        out = {}
        for k, trial in enumerate(self._trials(folder)):
            out[f"trial_{k}/value"] = np.asarray(trial.value)
            out.update({f"trial_{k}/{n}": np.asarray(v) for n, v in trial.params.items()})
        report = json.loads((folder / "multigait_calibration.json").read_text())
        for key in ("optimisation_error_mm", "validation_error_mm", "trials"):
            out[f"report/{key}"] = np.asarray(report[key])
        out.update({f"report/{n}": np.asarray(v) for n, v in report["parameters"].items()})
        return out

    def compare(self, work: Path, label: str) -> dict:
        return _same_arrays(self._arrays(work / "reference"), self._arrays(work / label))


def proxy_reference_child(path: str) -> None:
    from pliant.proxy.builders import multigait_proxy
    from pliant.proxy.references import Reference, setup

    surface = np.array([[0.0, 29.0, 0.0], [136.0, -29.0, 0.0], [68.0, 0.0, 0.0]])
    commands = np.repeat([[0.0, 0.0, 0.0, 1.0, 1.0], [0.0, 1.0, 1.0, 1.0, 1.0]], 10, axis=0)
    draft = Reference(commands, np.zeros((20, 3, 3)), surface, 0.01)
    points = setup("multigait").simulate(draft)(dict(multigait_proxy().parameters))
    Reference(commands, points, surface, 0.01).save(path)


# ------------------------------------------------------------------------ graph training
class Graph(Command):
    kind = "graph"
    result = "/checkpoint.pt"

    def __init__(self, args: argparse.Namespace) -> None:
        self.steps, self.eval_every = args.graph_steps, args.eval_every
        self.agent = {"hidden": 32, "d": 8, "lr": 1e-3, "batch_size": 32,
                      "learning_starts": 100, "option_limit": 20,
                      "updates_per_step": 0.25}  # fmt: skip

    def setup(self) -> dict:
        return {"command": ["pliant", "graph", "train", "Corridor", "--steps", str(self.steps),
                            "--eval-every", str(self.eval_every), "--eval-episodes", "2"],
                "agent": self.agent}  # fmt: skip

    def command(self, work: Path, label: str) -> list[str]:
        config = work / "graph_config.json"
        if not config.exists():
            config.write_text(json.dumps({"agent": self.agent}))
        options = ["--steps", str(self.steps), "--eval-every", str(self.eval_every)]
        options += ["--eval-episodes", "2", "--config", str(config), "--out", str(work / label)]
        return ["cli", "graph", "train", "Corridor", *options]

    def marker(self, work: Path, label: str) -> Path:
        return work / label / "tb"

    def clear(self, work: Path, label: str) -> None:
        shutil.rmtree(work / label, ignore_errors=True)

    def progress(self, work: Path, label: str) -> dict:
        history = work / label / "history.json"
        evaluations = json.loads(history.read_text())["evaluations"] if history.exists() else []
        return {"evaluations_at_kill": len(evaluations),
                "checkpoint_at_kill": (work / label / "checkpoint.pt").exists()}  # fmt: skip

    @staticmethod
    def _arrays(folder: Path) -> dict:
        import torch

        out = {}

        def flatten(prefix: str, value) -> None:
            if isinstance(value, dict):
                for k, v in value.items():
                    flatten(f"{prefix}/{k}", v)
            elif isinstance(value, list | tuple):
                for k, v in enumerate(value):
                    flatten(f"{prefix}/{k}", v)
            elif isinstance(value, torch.Tensor):
                out[prefix] = value.detach().cpu().numpy()
            elif value is None or isinstance(value, str | int):  # ints: NumPy's 128-bit states
                out[prefix] = np.asarray(str(value))
            else:
                out[prefix] = np.asarray(value)

        flatten("checkpoint", torch.load(folder / "checkpoint.pt", weights_only=False))
        evaluations = json.loads((folder / "history.json").read_text())["evaluations"]
        flatten("history", [{k: v for k, v in e.items() if k != "wall_s"} for e in evaluations])
        return out

    def compare(self, work: Path, label: str) -> dict:
        return _same_arrays(self._arrays(work / "reference"), self._arrays(work / label))


# ---------------------------------------------------------------------------------- study
def reference(kind, work: Path, warm_up: bool = True) -> float:
    """The uninterrupted run; returns its time from `kind.start`'s return to its end. A first
    run, not timed (`warm_up`), compiles and caches numba's kernels (and makes the files runs
    share)."""
    if warm_up:
        kind.finish(kind.start(work, "reference"), work, "reference")
    process = kind.start(work, "reference")
    clock = time.perf_counter()
    kind.finish(process, work, "reference")
    return time.perf_counter() - clock


def kill_time(seed: int, index: int, duration: float) -> float:
    """Run `index`'s kill time: uniform over the uninterrupted run's `duration` (seeded)."""
    return float(np.random.default_rng([seed, index]).uniform(0.0, duration))


def kill_and_resume(kind, work: Path, index: int, seed: int, duration: float) -> dict:
    """Run `index`, killed at a time drawn uniformly over `duration`, the uninterrupted run's
    time measured in this batch. A run that ends before its kill time (the machine's load
    changed) is reported as not killed, with its real time."""
    label = f"run_{index:03d}"
    kill_after = kill_time(seed, index, duration)
    clock = time.perf_counter()
    process = kind.start(work, label)
    started = time.perf_counter()
    try:
        process.wait(timeout=kill_after)
        killed = False  # it finished first (a loaded machine runs at another speed)
    except subprocess.TimeoutExpired:
        os.kill(process.pid, signal.SIGKILL)
        killed = True
    process.communicate()
    ran = time.perf_counter() - started
    progress = kind.progress(work, label)
    return {
        "run": index,
        "kill_after_s": round(kill_after, 3),
        "killed": killed,
        **({} if killed else {"ended_after_s": round(ran, 3)}),
        **progress,
        **kind.resume(work, label),
        **kind.compare(work, label),
        "seconds": round(time.perf_counter() - clock, 1),
    }


def summarise(runs: list[dict]) -> dict:
    killed = [r for r in runs if r["killed"]]
    # Killed with saved progress to resume from: a checkpoint, chunks of the collection,
    # records or cases of the snapshots, finished trials, a graph checkpoint.
    keys = ("chunks_at_kill", "records_at_kill", "cases_finished_at_kill", "trials_at_kill",
            "checkpoint_at_kill")  # fmt: skip
    saved = [r for r in killed if r.get("resumed_from") is not None or any(r.get(k) for k in keys)]
    return {
        "runs": len(runs),
        "killed": len(killed),
        "ended_before_kill_time": len(runs) - len(killed),
        "killed_with_saved_progress": len(saved),
        "identical": sum(r["identical"] for r in runs),
        "identical_among_killed": sum(r["identical"] for r in killed),
        "identical_among_killed_with_saved_progress": sum(r["identical"] for r in saved),
        "share_identical": sum(r["identical"] for r in runs) / max(len(runs), 1),
        "seconds_per_run": round(float(np.mean([r["seconds"] for r in runs])), 1) if runs else 0,
    }


#: How kill times are drawn; part of the settings (results under another protocol start afresh).
PROTOCOL = "uniform over the uninterrupted run's time, measured at the start of each batch"

KINDS = {
    "sb3": Training,
    "collect": Collection,
    "reduce": Reduction,
    "calibrate": Calibration,
    "graph": Graph,
}


def main() -> None:
    from pliant.files import write_json

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--kind", choices=tuple(KINDS), default="sb3")
    parser.add_argument("--runs", type=int, default=25, help="runs at most")
    parser.add_argument(
        "--killed",
        type=int,
        default=10**9,
        help="stop once this many runs were killed (default: do all --runs)",
    )
    parser.add_argument(
        "--batch-runs",
        type=int,
        default=0,
        help="time the reference again every this many runs (0: once a command)",
    )
    parser.add_argument("--seed", type=int, default=0, help="seed of the kill times")
    parser.add_argument("--steps", type=int, default=6000, help="sb3: training steps of a run")
    parser.add_argument("--checkpoint", type=int, default=640, help="sb3: steps a checkpoint")
    parser.add_argument("--samples", type=int, default=80, help="collect: training samples")
    parser.add_argument("--chunk", type=int, default=2, help="collect: samples a chunk")
    parser.add_argument("--cases", type=int, default=4, help="reduce: load cases")
    parser.add_argument("--trials", type=int, default=12, help="calibrate: trials")
    parser.add_argument("--graph-steps", type=int, default=240, help="graph: steps")
    parser.add_argument("--eval-every", type=int, default=30, help="graph: checkpoint period")
    parser.add_argument("--work", type=Path, help="default: runs/kill_resume_<kind>")
    parser.add_argument("--out", type=Path, help="default: experiments/results/reliability/")
    args = parser.parse_args()

    kind = KINDS[args.kind](args)
    work = args.work or ROOT / "runs" / f"kill_resume_{args.kind}"
    out = (
        args.out
        or ROOT / "experiments" / "results" / "reliability" / f"kill_resume_{args.kind}.json"
    )
    setup = {**kind.setup(), "seed": args.seed, "kill_time": PROTOCOL}
    report = json.loads(out.read_text()) if out.exists() else {}
    if report.get("setup") != setup or not (work / f"reference{kind.result}").exists():
        report = {"setup": setup, "batches": [], "results": []}
    work.mkdir(parents=True, exist_ok=True)
    runs = report["results"]
    # A batch: this command, or --batch-runs runs of it. Its uninterrupted run, timed at its
    # start on this machine, sets the window of its kill times (the load of a shared machine
    # changes from hour to hour).
    batch = None
    for index in range(len(runs), args.runs):
        if sum(r["killed"] for r in runs) >= args.killed:
            break
        if batch is None or 0 < args.batch_runs <= index - batch["first_run"]:
            load = os.getloadavg()[0]
            seconds = reference(kind, work, warm_up=batch is None)
            batch = {"batch": len(report["batches"]), "first_run": index,
                     "reference_s": round(seconds, 2), "load_average": round(load, 2)}  # fmt: skip
            report["batches"].append(batch)
            write_json(out, report)
            print(f"batch {batch['batch']}: reference run {seconds:.1f} s", flush=True)
        runs.append({"batch": batch["batch"],
                     **kill_and_resume(kind, work, index, args.seed, seconds)})  # fmt: skip
        report["summary"] = summarise(runs)
        write_json(out, report)
        print(json.dumps(runs[-1]), flush=True)
    print(json.dumps(report.get("summary"), indent=1))


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == "_child":
        child(*sys.argv[2:5])
    elif len(sys.argv) > 1 and sys.argv[1] == "_reduce":
        reduce_child(*sys.argv[2:4])
    elif len(sys.argv) > 1 and sys.argv[1] == "_proxy_reference":
        proxy_reference_child(sys.argv[2])
    else:
        main()
