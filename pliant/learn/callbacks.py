"""Training callbacks: full-state checkpoints, evaluation with success rate, and the
robust-training counters (diverged episodes, restarted workers) with the episode log."""

from __future__ import annotations

import copy
import csv
import json
import pickle
import random
import shutil
import signal
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import torch
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.vec_env import VecEnvWrapper, VecNormalize

from pliant.errors import TrainingError
from pliant.files import read_checked, replace, write_json, write_manifest
from pliant.learn.config import OFF_POLICY
from pliant.learn.evaluate import (  # noqa: F401 (the checkpoint finders' earlier home)
    check_checkpoint,
    intact_checkpoint,
    latest_checkpoint,
    run_episodes,
    save_policy,
)


def rng_state(model) -> dict:
    """Every random generator a run draws from: Python's, NumPy's global (replay sampling,
    minibatch permutations), PyTorch's (action sampling, dropout), the action space's (SAC's
    and TD3's warm-up actions)."""
    state = {
        "python": random.getstate(),
        "numpy": np.random.get_state(),  # noqa: NPY002 (SB3 draws from the global one)
        "torch": torch.get_rng_state(),
        "action_space": model.action_space.np_random.bit_generator.state,
    }
    if torch.cuda.is_available():
        state["cuda"] = torch.cuda.get_rng_state_all()
    return state


def set_rng_state(model, state: dict) -> None:
    random.setstate(state["python"])
    np.random.set_state(state["numpy"])  # noqa: NPY002
    torch.set_rng_state(state["torch"])
    model.action_space.np_random.bit_generator.state = state["action_space"]
    if "cuda" in state and torch.cuda.is_available():
        torch.cuda.set_rng_state_all(state["cuda"])


class TrainingState:
    """Counters kept by the callbacks and saved with each checkpoint."""

    def __init__(self) -> None:
        self.diverged = 0
        self.restarts = 0
        self.episodes = 0
        #: training wall time up to the last checkpoint, over all sessions of the run.
        self.wall_seconds = 0.0


class RobustnessCallback(BaseCallback):
    """Counts diverged episodes (``info["diverged"]``) and restarted workers
    (``info["worker_restarted"]``) in TensorBoard scalars ``robust/diverged_episodes`` and
    ``robust/worker_restarts``, and appends every finished episode (step, return, length,
    success, diverged) to ``episodes.csv``."""

    def __init__(self, run_dir: Path, counters: TrainingState) -> None:
        super().__init__()
        self.path = run_dir / "episodes.csv"
        self.counters = counters
        self._file = None
        self._writer = None

    def _on_training_start(self) -> None:
        new = not self.path.exists()
        self._file = open(self.path, "a", newline="")  # noqa: SIM115 (closed at training end)
        self._writer = csv.writer(self._file)
        if new:
            self._writer.writerow(["step", "return", "length", "success", "diverged"])

    def _on_step(self) -> bool:
        for done, info in zip(self.locals["dones"], self.locals["infos"], strict=True):
            if info.get("worker_restarted"):
                self.counters.restarts += 1
            if not done:
                continue
            diverged = bool(info.get("diverged"))
            self.counters.diverged += diverged
            self.counters.episodes += 1
            episode = info.get("episode")
            if episode is not None:
                success = info.get("is_success")
                self._writer.writerow(
                    [
                        self.num_timesteps,
                        f"{episode['r']:.6g}",
                        episode["l"],
                        "" if success is None else int(bool(success)),
                        int(diverged),
                    ]
                )
                self._file.flush()
        self.logger.record("robust/diverged_episodes", self.counters.diverged)
        self.logger.record("robust/worker_restarts", self.counters.restarts)
        return True

    def _on_training_end(self) -> None:
        if self._file is not None:
            self._file.close()


class EvalCallback(BaseCallback):
    """Every `freq` steps (and at the end: the final policy, after its last update),
    `episodes` deterministic episodes on a separate environment with the training normaliser's
    statistics: ``eval/success_rate``, ``eval/mean_reward`` in TensorBoard, the learning curve
    in ``evaluations.json``, the best model so far in ``best/``."""

    def __init__(self, run_dir: Path, env, freq: int, episodes: int, config) -> None:
        super().__init__()
        self.run_dir = run_dir
        self.env = env
        self.freq = int(freq)
        self.episodes = int(episodes)
        self.config = config
        self.path = run_dir / "evaluations.json"
        self.curve: list[dict] = []
        self.next_eval = self.freq
        self.best = -np.inf

    def load_curve(self, up_to_step: int) -> None:
        """Resume: keep the evaluations made before the checkpoint."""
        if self.path.exists():
            curve = read_checked(self.path, lambda p: json.loads(p.read_text()), "a learning curve")
            self.curve = [e for e in curve if e["step"] <= up_to_step]
        if self.curve:
            self.next_eval = self.curve[-1]["step"] + self.freq
            self.best = max(self._score(e) for e in self.curve)

    @staticmethod
    def _score(entry: dict) -> float:
        s = entry.get("success_rate")
        return entry["mean_return"] if s is None else s + 1e-9 * entry["mean_return"]

    def evaluate(self) -> dict:
        vecnorm = self.model.get_vec_normalize_env()
        result = run_episodes(
            self.model,
            self.env,
            self.episodes,
            normalize_obs=None if vecnorm is None else vecnorm.normalize_obs,
            seed=10_000,
        )
        entry = {"step": int(self.num_timesteps), **result.to_dict()}
        self.curve = [e for e in self.curve if e["step"] != entry["step"]] + [entry]
        write_json(self.path, self.curve)
        if result.success_rate is not None:
            self.logger.record("eval/success_rate", result.success_rate)
        self.logger.record("eval/mean_reward", result.mean_return)
        self.logger.record("eval/mean_ep_length", result.mean_length)
        if self._score(entry) > self.best:
            self.best = self._score(entry)
            save_policy(
                self.model,
                self.run_dir / "best",
                self.config.algo,
                self.config.env_id,
                self.config.env_kwargs,
                vecnorm,
            )
        return entry

    def _on_step(self) -> bool:
        if self.freq > 0 and self.episodes > 0 and self.num_timesteps >= self.next_eval:
            while self.next_eval <= self.num_timesteps:
                self.next_eval += self.freq
            # At the run's last step the policy still has its last update to come (after the
            # rollout): the evaluation at training end is the final policy's.
            if self.num_timesteps < self.model._total_timesteps:
                self.evaluate()
        return True

    def _on_training_end(self) -> None:
        if self.episodes <= 0:
            return
        if not self.curve or self.curve[-1]["step"] != self.num_timesteps:
            self.evaluate()
            self.logger.dump(self.num_timesteps)


class CheckpointCallback(BaseCallback):
    """Every `freq` steps, the whole training state in ``checkpoints/step_<N>/``: the model
    (parameters, optimisers, counters, the last observations), the replay buffer of an
    off-policy learner, the VecNormalize statistics, the random generators' states, every
    environment's snapshot and the callbacks' counters.

    Saved when a rollout starts, where the previous rollout is stored and trained on: nothing
    is half done. Resuming from it (:func:`pliant.learn.training.train` with ``resume=True``)
    continues as if the run had not stopped.

    :meth:`request_stop` (SIGTERM or SIGINT, see :func:`stop_on_signals`) saves a checkpoint
    at the next rollout start and ends the training there.
    """

    def __init__(self, run_dir: Path, freq: int, keep: int, config, counters: TrainingState):
        super().__init__()
        self.folder = run_dir / "checkpoints"
        self.freq = int(freq)
        self.keep = int(keep)
        self.config = config
        self.counters = counters
        self.next_save = self.freq
        self.last_saved = -1
        #: the signal that asked the run to stop (its name), None while it runs on.
        self.stop_requested: str | None = None
        self._stopping = False

    def request_stop(self, reason: str) -> None:
        self.stop_requested = reason

    def _on_training_start(self) -> None:
        self._clock = time.perf_counter()
        self._wall_before = self.counters.wall_seconds

    def _on_step(self) -> bool:
        return not self._stopping

    def _on_rollout_start(self) -> None:
        if self.stop_requested is not None:
            self.save()
            self._stopping = True  # the rollout's first step ends the training
            return
        if self.freq > 0 and self.num_timesteps >= self.next_save:
            while self.next_save <= self.num_timesteps:
                self.next_save += self.freq
            self.save()

    def _on_training_end(self) -> None:
        # Only a run that reached its end is at a consistent point: one stopped by a callback
        # stops mid-rollout; its last checkpoint stands.
        if self.model.num_timesteps >= self.model._total_timesteps:
            self.save()

    def save(self) -> Path | None:
        step = int(self.num_timesteps)
        if step == self.last_saved:
            return None
        final = self.folder / f"step_{step}"
        tmp = self.folder / f".step_{step}.tmp"
        shutil.rmtree(tmp, ignore_errors=True)
        try:
            self._write(tmp, step)
        except OSError as exc:  # a full disk, a folder gone: the earlier checkpoints stand
            shutil.rmtree(tmp, ignore_errors=True)
            raise TrainingError(
                f"step {step}: cannot write the checkpoint {final} ({exc}); the earlier"
                " checkpoints are intact: free space and go on with --resume"
            ) from exc
        shutil.rmtree(final, ignore_errors=True)
        replace(tmp, final)  # durably: its files on the disk first
        self.last_saved = step
        for old in sorted(self.folder.glob("step_*"), key=lambda p: int(p.name[5:]))[: -self.keep]:
            shutil.rmtree(old, ignore_errors=True)
        return final

    def _write(self, tmp: Path, step: int) -> None:
        env = self.model.get_env()
        vecnorm = self.model.get_vec_normalize_env()
        save_policy(
            self.model, tmp, self.config.algo, self.config.env_id, self.config.env_kwargs, vecnorm
        )
        if self.config.algo in OFF_POLICY:
            self.model.save_replay_buffer(tmp / "replay_buffer.pkl")
        snapshots = env.env_method("snapshot")
        self.counters.wall_seconds = self._wall_before + time.perf_counter() - self._clock
        state = {
            "num_timesteps": step,
            "rng": rng_state(self.model),
            "env_snapshots": None if any(s is None for s in snapshots) else snapshots,
            "vecnorm_returns": None if vecnorm is None else vecnorm.returns.copy(),
            "counters": vars(self.counters).copy(),
            # RecurrentPPO's LSTM states in flight (its load re-creates them as zeros).
            "lstm_states": copy.deepcopy(getattr(self.model, "_last_lstm_states", None)),
        }
        with open(tmp / "state.pkl", "wb") as f:
            pickle.dump(state, f)
        # Read back on resume: a damaged file (a full disk, a copy cut short) is told apart.
        write_manifest(tmp)


@contextmanager
def stop_on_signals(checkpoints: CheckpointCallback) -> Iterator[None]:
    """While training: SIGTERM or SIGINT asks `checkpoints` to save at the next rollout start
    and stop there (a resume from it is exact); a second one acts as it would have without
    this (SIGINT: KeyboardInterrupt). Outside the main thread signals cannot be caught: no-op."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {s: signal.getsignal(s) for s in (signal.SIGTERM, signal.SIGINT)}

    def handler(number, frame) -> None:
        for s, h in previous.items():
            signal.signal(s, h)
        checkpoints.request_stop(signal.Signals(number).name)

    for s in previous:
        signal.signal(s, handler)
    try:
        yield
    finally:
        for s, h in previous.items():
            signal.signal(s, h)


def restore_checkpoint(model, folder: Path, counters: TrainingState) -> dict:
    """Put a checkpoint's replay buffer, environment snapshots, normaliser returns, random
    generators and counters back into a model loaded from it (``force_reset=False``)."""
    with open(folder / "state.pkl", "rb") as f:
        state = pickle.load(f)
    if (folder / "replay_buffer.pkl").exists():
        model.load_replay_buffer(folder / "replay_buffer.pkl")
    env = model.get_env()
    if state["env_snapshots"] is None:
        # The environment cannot be snapshot: the episodes in flight restart.
        model._last_obs = None
    else:
        for i, snapshot in enumerate(state["env_snapshots"]):
            env.env_method("restore", snapshot, indices=[i])
    vecnorm = model.get_vec_normalize_env()
    if isinstance(vecnorm, VecNormalize) and state["vecnorm_returns"] is not None:
        vecnorm.returns = state["vecnorm_returns"].copy()
    inner = env
    while isinstance(inner, VecEnvWrapper):
        inner = inner.venv
    inner._reset_seeds()  # the seeds SB3's load gave the environments apply at reset only
    if state.get("lstm_states") is not None:
        model._last_lstm_states = state["lstm_states"]
    set_rng_state(model, state["rng"])
    for k, v in state["counters"].items():
        setattr(counters, k, v)
    return state
