"""``pliant train``: a Stable-Baselines3 run with vectorised workers, normalisation,
evaluation, full-state checkpoints and exact resume.

A run lives in one folder::

    RUN/config.yaml          the resolved TrainConfig (what --resume reads)
    RUN/checkpoints/step_N/  model.zip, replay_buffer.pkl, vecnormalize.pkl, state.pkl,
                             manifest.json (sizes and SHA-256 of the others)
    RUN/tb/                  TensorBoard logs
    RUN/evaluations.json     the learning curve (evaluation success rate and return)
    RUN/episodes.csv         every training episode (step, return, length, success, diverged)
    RUN/best/, RUN/final/    model.zip + vecnormalize.pkl + meta.json
    RUN/bc.json, RUN/cloned/ with behaviour cloning: the fit, and the policy as cloned
    RUN/summary.json, RUN/learning_curve.png, RUN/eval.gif

Exact resume: ``train(config, run_dir, resume=True)`` loads the latest intact checkpoint (each
checkpoint's files are checked against the sizes and SHA-256 hashes of its ``manifest.json``;
a damaged one is skipped with a CheckpointWarning naming it, and a run with none intact stops
with a CorruptFileError naming the damage) and ends with
the same parameters as an uninterrupted run, bit for bit, when the environments run in this
process or in one worker (``n_envs=1``, tested). With several worker processes the result is
the same too as long as each worker's environment is deterministic given its snapshot (Pliant's
environments are); what is not reproducible is the wall-clock data (times in the Monitor
logs), a worker restarted after a crash (its new environment is reset unseeded), and, with
PyTorch, a different number of threads or another machine (floating-point reductions).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from stable_baselines3.common.utils import set_random_seed
from stable_baselines3.common.vec_env import VecNormalize

from pliant.errors import TrainingError
from pliant.files import write_json
from pliant.learn.callbacks import (
    CheckpointCallback,
    EvalCallback,
    RobustnessCallback,
    TrainingState,
    intact_checkpoint,
    restore_checkpoint,
    stop_on_signals,
)
from pliant.learn.config import OFF_POLICY, TrainConfig, sb3_kwargs
from pliant.learn.evaluate import algorithm_class, save_policy
from pliant.learn.updates import fast_update_kwargs
from pliant.learn.vec import make_env, make_vec_env


@dataclass
class TrainResult:
    model: object
    run_dir: Path
    summary: dict


def _vec_normalize(venv, config: TrainConfig):
    if not config.normalize:
        return venv
    kwargs = config.normalize if isinstance(config.normalize, dict) else {}
    kwargs.setdefault("gamma", config.hyperparams.get("gamma", 0.99))
    return VecNormalize(venv, **kwargs)


def _environment(env_id: str, env_kwargs: dict | None):
    """`make_env`, with keywords the environment does not take named in a TrainingError."""
    try:
        return make_env(env_id, env_kwargs)
    except TypeError as exc:  # gymnasium.make re-raises the constructor's, with the keywords
        raise TrainingError(f"cannot make {env_id} with {env_kwargs or {}}: {exc}") from exc


def train(
    config: TrainConfig | None = None,
    run_dir: str | Path = "runs/run",
    *,
    resume: bool = False,
    progress_bar: bool = False,
    total_timesteps: int | None = None,
    extra_callbacks: list | None = None,
    verbose: int = 0,
) -> TrainResult:
    """Train (or, with `resume`, continue the run in `run_dir` from its latest checkpoint).

    `total_timesteps` overrides the configuration's (on resume: extend or shorten the run).
    """
    run_dir = Path(run_dir)
    checkpoint = None
    if resume:
        if not (run_dir / "config.yaml").exists():
            raise FileNotFoundError(f"nothing to resume in {run_dir}: no config.yaml")
        config = TrainConfig.load(run_dir / "config.yaml")
        checkpoint = intact_checkpoint(run_dir)
        if checkpoint is None:
            raise FileNotFoundError(f"nothing to resume in {run_dir}: no checkpoint yet")
    if config is None:
        raise ValueError("give a TrainConfig, or resume=True with a run folder")
    if total_timesteps is not None:
        config.total_timesteps = int(total_timesteps)
    run_dir.mkdir(parents=True, exist_ok=True)
    config.save(run_dir / "config.yaml")

    set_random_seed(config.seed)
    # The environment keywords are checked here, in the learner, before any worker starts: a
    # worker that cannot build its environment dies with a traceback of its own.
    eval_env = _environment(config.env_id, config.eval_env_kwargs or config.env_kwargs)
    if config.eval_env_kwargs and config.eval_env_kwargs != config.env_kwargs:
        _environment(config.env_id, config.env_kwargs).close()
    venv = make_vec_env(
        config.env_id,
        config.n_envs,
        env_kwargs=config.env_kwargs,
        backend=config.vec_env,
        ray_address=config.ray_address,
    )
    algo_class = algorithm_class(config.algo)
    counters = TrainingState()
    try:
        if checkpoint is not None:
            if (checkpoint / "vecnormalize.pkl").exists():
                venv = VecNormalize.load(str(checkpoint / "vecnormalize.pkl"), venv)
            model = algo_class.load(
                checkpoint / "model.zip",
                env=venv,
                device=config.device,
                force_reset=False,
                tensorboard_log=str(run_dir / "tb"),
            )
            state = restore_checkpoint(model, checkpoint, counters)
            start_step = state["num_timesteps"]
        else:
            venv = _vec_normalize(venv, config)
            kwargs = sb3_kwargs(config.hyperparams)
            if config.fast_updates:
                kwargs = fast_update_kwargs(config.algo, kwargs)
            try:
                model = algo_class(
                    env=venv,
                    seed=config.seed,
                    device=config.device,
                    tensorboard_log=str(run_dir / "tb"),
                    verbose=verbose,
                    **kwargs,
                )
            except (TypeError, ValueError, AssertionError) as exc:  # SB3's and torch's checks
                raise TrainingError(
                    f"{config.algo} cannot be built with the hyper-parameters"
                    f" {config.hyperparams}: {exc}"
                ) from exc
            start_step = 0
            if config.bc:
                from pliant.learn.bc import pretrain

                report = pretrain(model, config)
                write_json(run_dir / "bc.json", report)
                # the cloned policy as it is before any RL, to evaluate beside the final one
                save_policy(
                    model, run_dir / "cloned", config.algo, config.env_id, config.env_kwargs,
                    model.get_vec_normalize_env(),
                )  # fmt: skip

        checkpoints = CheckpointCallback(
            run_dir, config.checkpoint_freq, config.keep_checkpoints, config, counters
        )
        evaluation = EvalCallback(run_dir, eval_env, config.eval_freq, config.eval_episodes, config)
        robust = RobustnessCallback(run_dir, counters)
        if checkpoint is not None:
            checkpoints.last_saved = start_step
            if config.checkpoint_freq > 0:
                checkpoints.next_save = (start_step // config.checkpoint_freq + 1) * (
                    config.checkpoint_freq
                )
            evaluation.load_curve(start_step)
            _truncate_episode_log(run_dir / "episodes.csv", start_step)
        elif (run_dir / "episodes.csv").exists():
            (run_dir / "episodes.csv").unlink()
            (run_dir / "evaluations.json").unlink(missing_ok=True)

        remaining = config.total_timesteps - model.num_timesteps
        clock = time.perf_counter()
        if remaining > 0:
            with stop_on_signals(checkpoints):
                model.learn(
                    remaining,
                    callback=[robust, evaluation, checkpoints, *(extra_callbacks or [])],
                    reset_num_timesteps=checkpoint is None,
                    tb_log_name="run",
                    progress_bar=progress_bar,
                )
        wall = time.perf_counter() - clock
        vecnorm = model.get_vec_normalize_env()
        # A signal stopped the run before its end: no final/, no video (--resume goes on).
        stopped = checkpoints.stop_requested
        if model.num_timesteps >= config.total_timesteps:
            stopped = None
        if stopped is None:
            save_policy(
                model, run_dir / "final", config.algo, config.env_id, config.env_kwargs, vecnorm
            )
        summary = {
            "env_id": config.env_id,
            "algo": config.algo,
            "steps": int(model.num_timesteps),
            "resumed_from": start_step if checkpoint is not None else None,
            "wall_seconds": counters.wall_seconds,
            "wall_seconds_this_session": wall,
            "steps_per_second_this_session": (model.num_timesteps - start_step) / max(wall, 1e-9),
            "diverged_episodes": counters.diverged,
            "worker_restarts": counters.restarts,
            "final_evaluation": evaluation.curve[-1] if evaluation.curve else None,
            # SIGTERM or SIGINT: stopped at a checkpoint, `--resume` goes on from it exactly.
            "stopped_by": stopped,
        }
        write_json(run_dir / "summary.json", summary)
        if evaluation.curve:
            from pliant.learn.plots import plot_learning_curve

            plot_learning_curve(run_dir)
        if config.video_episodes > 0 and stopped is None:
            from pliant.learn.evaluate import evaluate_saved

            evaluate_saved(
                run_dir / "final",
                episodes=config.video_episodes,
                gif=run_dir / "eval.gif",
                gif_episodes=config.video_episodes,
            )
        return TrainResult(model, run_dir, summary)
    finally:
        venv.close()
        eval_env.close()


def _truncate_episode_log(path: Path, step: int) -> None:
    """Resume: drop the episodes logged after the checkpoint (the interrupted run's)."""
    if not path.exists():
        return
    lines = path.read_text().splitlines()
    kept = [lines[0]] + [line for line in lines[1:] if int(line.split(",")[0]) <= step]
    path.write_text("\n".join(kept) + "\n")


def parameters(model) -> dict[str, np.ndarray]:
    """The policy's parameters as arrays (comparison of runs)."""
    return {k: v.detach().cpu().numpy().copy() for k, v in model.policy.state_dict().items()}


__all__ = ["OFF_POLICY", "TrainConfig", "TrainResult", "parameters", "train"]
