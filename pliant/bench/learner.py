"""What the learner costs per environment step, apart from the simulation (`pliant bench
--learner`).

A training step is a simulation step plus the learner's share: the policy's forward pass that
picks the action, the replay or rollout buffer, and the gradient updates spread over the steps
(SAC: ``gradient_steps`` updates every ``train_freq`` steps of ``n_envs`` environments; PPO:
``n_epochs`` passes over ``n_steps * n_envs`` samples in minibatches). To see that share alone,
the run's own configuration (``pliant/learn/configs``: the thesis' 3 x 512 networks) trains on
a stand-in environment with the task's observation and action spaces whose step costs nothing.

The arithmetic is counted, not guessed: PyTorch's FLOP counter (``torch.utils.flop_counter``)
gives the floating-point operations of the learner's work, and the same process times a
256 x 512 by 512 x 512 matrix product, the kind of operation the updates are made of. Their
ratio says whether the updates run at the machine's matrix-product speed (then only less
arithmetic or more cores make them faster) or lose time elsewhere (threads, copies,
per-update overheads). Measured side by side in one process, the ratio holds on a shared,
noisy machine where the times alone do not.

:func:`training_speed` times the real thing: `pliant train` (:func:`pliant.learn.train`) on the
task itself, its configuration as the thesis run has it, environment steps per second with the
updates included, in a window after the warm-up (SAC: after ``learning_starts``; PPO: one
rollout of ``n_steps`` per environment and its epochs), with Stable-Baselines3's own updates or
Pliant's (:mod:`pliant.learn.updates`). Wall time is the machine's of the moment; the CPU time
of the learner's process and of its environment workers is what the run itself spent.
"""

from __future__ import annotations

import os
import statistics
import tempfile
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import gymnasium as gym
import numpy as np
from stable_baselines3.common.callbacks import BaseCallback

import pliant.envs  # noqa: F401  (registers the pliant/ ids with Gymnasium)
from pliant.errors import TrainingError
from pliant.learn.config import ALGOS, OFF_POLICY, load_config, sb3_kwargs
from pliant.learn.evaluate import algorithm_class
from pliant.learn.training import train
from pliant.learn.updates import fast_update_kwargs


class FreeStepEnv(gym.Env):
    """A task's observation and action spaces around a step that costs nothing: random
    observations from the space, reward 0, episodes of `episode_steps`."""

    def __init__(self, observation_space, action_space, episode_steps: int = 30) -> None:
        self.observation_space = observation_space
        self.action_space = action_space
        self.episode_steps = episode_steps
        self._t = 0

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        self.observation_space.seed(seed)
        self._t = 0
        return self.observation_space.sample(), {}

    def step(self, action):
        self._t += 1
        return self.observation_space.sample(), 0.0, False, self._t >= self.episode_steps, {}


@dataclass(frozen=True)
class LearnerCost:
    env_id: str
    algo: str
    net_arch: list
    n_envs: int
    torch_threads: int
    env_steps: int
    ms_per_env_step: float  # median over repeats: what the learner adds to each training step
    learner_bound_steps_per_s: float  # training's ceiling if the simulation cost nothing
    gflop_per_env_step: float  # PyTorch's FLOP counter: forward and backward products
    matmul_gflop_per_s: float  # median, same process, same threads
    share_of_matmul_speed: float  # (gflop / time) / matmul speed
    repeats: list

    def to_dict(self) -> dict:
        return asdict(self)


def _matmul_speed(repeats: int = 200, dtype=None, warmup: int = 10) -> float:
    """GFLOP/s of a 256 x 512 by 512 x 512 product in `dtype` (default float32)."""
    import torch

    dtype = dtype or torch.float32
    a, b = torch.randn(256, 512, dtype=dtype), torch.randn(512, 512, dtype=dtype)
    for _ in range(warmup):
        a @ b
    t0 = time.perf_counter()
    for _ in range(repeats):
        a @ b
    return 2.0 * 256 * 512 * 512 * repeats / (time.perf_counter() - t0) / 1e9


def learner_cost(
    env_id: str,
    algo: str,
    *,
    env_steps: int = 512,
    repeats: int = 3,
    torch_threads: int = 1,
    hyperparams: dict | None = None,
    seed: int = 0,
) -> LearnerCost:
    """Time `env_steps` training steps of `algo` with `env_id`'s configuration on a stand-in
    of the task whose step is free (module docstring). `hyperparams` override the config's
    (e.g. a smaller network for a quick check)."""
    import torch
    from stable_baselines3.common.vec_env import DummyVecEnv
    from torch.utils.flop_counter import FlopCounterMode

    if env_steps < 1 or repeats < 1 or torch_threads < 1:
        raise TrainingError(
            f"env_steps, repeats and torch_threads must be >= 1, got {env_steps}, {repeats},"
            f" {torch_threads}"
        )
    if algo not in ALGOS:
        raise TrainingError(f"algo must be one of {', '.join(ALGOS)}, got {algo!r}")
    config = load_config(env_id, algo)
    params = {**config.hyperparams, **(hyperparams or {})}
    try:
        task = gym.make(env_id)
    except gym.error.Error as exc:
        raise TrainingError(f"no environment {env_id!r} to time the learner on: {exc}") from exc
    spaces = (task.observation_space, task.action_space)
    episode = getattr(task.spec, "max_episode_steps", None) or 30
    task.close()

    saved = torch.get_num_threads()
    torch.set_num_threads(torch_threads)
    try:
        venv = DummyVecEnv([lambda: FreeStepEnv(*spaces, episode)] * config.n_envs)
        kwargs = fast_update_kwargs(algo, sb3_kwargs(params))  # as `pliant train` runs it
        if algo in OFF_POLICY:
            kwargs["learning_starts"] = 0  # updates from the first step: the steady state
        else:
            # one rollout of n_steps per environment holds the whole update cycle
            env_steps = max(env_steps, kwargs.get("n_steps", 2048) * config.n_envs)
        model = algorithm_class(algo)(env=venv, seed=seed, device="cpu", verbose=0, **kwargs)
        model.learn(min(env_steps, 64 * config.n_envs))  # buffers and kernels warmed up
        counter = FlopCounterMode(display=False)  # counts per operation, records no trace
        with counter:
            model.learn(env_steps, reset_num_timesteps=False)
        gflop = counter.get_total_flops() / env_steps / 1e9
        times, matmul = [], []
        for _ in range(repeats):
            matmul.append(_matmul_speed())
            t0 = time.perf_counter()
            model.learn(env_steps, reset_num_timesteps=False)
            times.append((time.perf_counter() - t0) / env_steps)
        venv.close()
    finally:
        torch.set_num_threads(saved)
    per_step = statistics.median(times)
    speed = statistics.median(matmul)
    return LearnerCost(
        env_id=env_id,
        algo=algo,
        net_arch=list(params.get("policy_kwargs", {}).get("net_arch", [])),
        n_envs=config.n_envs,
        torch_threads=torch_threads,
        env_steps=env_steps,
        ms_per_env_step=per_step * 1e3,
        learner_bound_steps_per_s=1.0 / per_step,
        gflop_per_env_step=gflop,
        matmul_gflop_per_s=speed,
        share_of_matmul_speed=float(np.clip(gflop / per_step / speed, 0.0, np.inf)),
        repeats=[t * 1e3 for t in times],
    )


def bfloat16_speedup(repeats: int = 5) -> dict:
    """Whether bfloat16 products would pay on this CPU: the speed of the learner's kind of
    product in bfloat16 over float32, measured in turn on one PyTorch thread, with the
    instruction set PyTorch found. It depends on the CPU: 2.3x where the host had AVX512-BF16
    (2026-12-06), 0.025x on an AVX2 host of the same kind (2026-12-07), where a SAC update of
    the thesis' 3 x 512 networks under ``torch.autocast("cpu", torch.bfloat16)`` took 16x as
    long as in float32 (docs/concepts/speed.md)."""
    import torch

    saved = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        fp32, bf16 = [], []
        for _ in range(repeats):
            fp32.append(_matmul_speed(20, torch.float32, warmup=2))
            bf16.append(_matmul_speed(2, torch.bfloat16, warmup=1))
    finally:
        torch.set_num_threads(saved)
    return {
        "cpu_capability": torch.backends.cpu.get_cpu_capability(),
        "matmul_fp32_gflop_per_s": statistics.median(fp32),
        "matmul_bf16_gflop_per_s": statistics.median(bf16),
        "bf16_over_fp32": statistics.median(bf16) / statistics.median(fp32),
    }


# The thesis' learning runs whose learner the bench times (configs/<Env>.yaml).
THESIS_RUNS = (("pliant/CartStemContact-v0", "SAC"), ("pliant/TrunkSpaceDebris-v0", "PPO"))


def report_learner(*, quick: bool, out, console, torch_threads: int = 1) -> list[LearnerCost]:
    """Time the learner of each thesis run, print a table, write the JSON atomically."""
    from rich.table import Table

    from pliant.files import write_json

    rows = [
        learner_cost(
            env_id,
            algo,
            env_steps=128 if quick else 1024,
            repeats=1 if quick else 3,
            torch_threads=torch_threads,
        )
        for env_id, algo in THESIS_RUNS
    ]
    table = Table(title="the learner alone (stand-in task, free step), per environment step")
    for col in ("run", "net", "ms", "steps/s ceiling", "GFLOP", "matmul GFLOP/s", "share"):
        table.add_column(col, justify="right")
    for r in rows:
        table.add_row(
            f"{r.algo} {r.env_id.split('/')[-1]}",
            "x".join(map(str, r.net_arch)),
            f"{r.ms_per_env_step:.1f}",
            f"{r.learner_bound_steps_per_s:.1f}",
            f"{r.gflop_per_env_step:.2f}",
            f"{r.matmul_gflop_per_s:.1f}",
            f"{100 * r.share_of_matmul_speed:.0f} %",
        )
    console.print(table)
    bf16 = bfloat16_speedup(repeats=1 if quick else 5)
    console.print(
        f"bfloat16 product on this CPU ({bf16['cpu_capability']}):"
        f" {bf16['bf16_over_fp32']:.2f}x the float32 one (one thread, measured in turn)"
    )
    write_json(out, {"learner": [r.to_dict() for r in rows], "bfloat16": bf16, "quick": quick})
    console.print(f"saved {out}")
    return rows


def _process_cpu(pid: int) -> float:
    """CPU seconds (user + system) a running process has used, from /proc (Linux); nan
    elsewhere."""
    try:
        text = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return float("nan")
    fields = text[text.rindex(")") + 2 :].split()  # after the command's name: state, ppid, ...
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


class TrainingClock(BaseCallback):
    """Times a training run from the first rollout that starts at or after `after` steps (the
    updates of SAC start after ``learning_starts``) to its end: wall and CPU time of this
    process, CPU time of the environment workers, and the updates apart (SB3 updates between a
    rollout's end and the next one's start, or the run's end)."""

    def __init__(self, after: int) -> None:
        super().__init__()
        self.after = after
        self.start: dict | None = None
        self.result: dict | None = None
        self.update_wall = self.update_cpu = 0.0
        self.updates = 0
        self._ended: tuple[float, float] | None = None

    def _workers(self) -> list[int]:
        venv = self.training_env
        while hasattr(venv, "venv"):  # VecNormalize and other wrappers
            venv = venv.venv
        return [p.pid for p in getattr(venv, "processes", [])]

    def _now(self) -> dict:
        workers = sum(_process_cpu(pid) for pid in self._workers())
        return {
            "steps": self.num_timesteps, "wall": time.perf_counter(), "cpu": time.process_time(),
            "workers_cpu": workers, "update_wall": self.update_wall,
            "update_cpu": self.update_cpu, "updates": self.updates,
        }  # fmt: skip

    def _between(self) -> None:
        """A rollout starts or the run ends: what ran since the last rollout ended was SB3's
        update (``train``) and its bookkeeping."""
        if self._ended is not None:
            wall, cpu = self._ended
            self.update_wall += time.perf_counter() - wall
            self.update_cpu += time.process_time() - cpu
            self.updates += 1
            self._ended = None

    def _on_rollout_start(self) -> None:
        self._between()
        if self.start is None and self.num_timesteps >= self.after:
            self.start = self._now()

    def _on_rollout_end(self) -> None:
        if self.start is not None:
            self._ended = (time.perf_counter(), time.process_time())

    def _on_step(self) -> bool:
        return True

    def _on_training_end(self) -> None:
        self._between()
        if self.start is None:
            return
        end = self._now()
        d = {k: end[k] - self.start[k] for k in end}
        steps = d["steps"]
        self.result = {
            "window_steps": steps,
            "updates": d["updates"],
            "wall_s": d["wall"],
            "steps_per_s": steps / d["wall"],
            "learner_cpu_ms_per_step": 1e3 * d["cpu"] / steps,
            "workers_cpu_ms_per_step": 1e3 * d["workers_cpu"] / steps,
            "update_cpu_ms_per_step": 1e3 * d["update_cpu"] / steps,
            "update_wall_ms_per_step": 1e3 * d["update_wall"] / steps,
            "update_cpu_ms_each": 1e3 * d["update_cpu"] / max(d["updates"], 1),
        }


def training_speed(
    env_id: str,
    algo: str,
    *,
    fast_updates: bool = True,
    quick: bool = False,
    window: int | None = None,
    seed: int = 0,
    overrides: dict | None = None,
) -> dict:
    """Environment steps per second of `pliant train` with `env_id`'s configuration for `algo`
    (module docstring), updates included, with Pliant's updates or (``fast_updates=False``)
    SB3's own. SAC: the window is `window` steps (default 400) after ``learning_starts``;
    PPO: one rollout and its epochs. `quick`: SAC's warm-up is 256 steps and its window 128,
    PPO's rollout 256 steps per environment (the thesis' 2048: the updates' share of a step,
    epochs times minibatches per sample, is the same).

    The result adds ``cpu_bound_steps_per_s``: the rate if the learner and each worker had a
    core of their own (SB3 steps the workers and then updates, in turn), from the CPU times:
    steps / (learner CPU + workers' CPU / n_envs), the figure that a shared host's load does
    not move. `overrides`: TrainConfig fields over the configuration's (a quick check's)."""
    settings = {"seed": seed, "eval_freq": 0, "eval_episodes": 0, "checkpoint_freq": 0}
    settings.update(video_episodes=0, fast_updates=fast_updates, **(overrides or {}))
    config = load_config(env_id, algo, overrides=settings)
    hyper = config.hyperparams
    if algo in OFF_POLICY:
        if quick:
            hyper["learning_starts"] = 256
        after = hyper.get("learning_starts", 100)  # SB3's default
        config.total_timesteps = after + (window or (128 if quick else 400))
    else:
        if quick:
            hyper["n_steps"] = 256
        after = 0
        config.total_timesteps = hyper.get("n_steps", 2048) * config.n_envs
    clock = TrainingClock(after)
    with tempfile.TemporaryDirectory() as tmp:
        train(config, Path(tmp) / "run", extra_callbacks=[clock])
    if clock.result is None:
        raise TrainingError(f"{algo} on {env_id}: no update inside the window to time")
    r = clock.result
    per_step = r["learner_cpu_ms_per_step"] + r["workers_cpu_ms_per_step"] / config.n_envs
    import torch

    return {
        "env_id": env_id, "algo": algo, "fast_updates": fast_updates, "quick": quick,
        "n_envs": config.n_envs, "vec_env": config.vec_env,
        "net_arch": list(hyper.get("policy_kwargs", {}).get("net_arch", [])),
        "warmup_steps": after, "torch_threads": torch.get_num_threads(),
        **r, "cpu_bound_steps_per_s": 1e3 / per_step, "load_average": os.getloadavg()[0],
    }  # fmt: skip


def report_training(*, quick: bool, out, console, repeats: int = 1) -> list[dict]:
    """`pliant bench --training`: each thesis run trained for a short window with SB3's
    updates and with Pliant's, in turn, `repeats` times; a table and the JSON."""
    from rich.table import Table

    from pliant.files import write_json

    rows = []
    for env_id, algo in THESIS_RUNS:
        for _ in range(repeats):
            for fast in (False, True):
                rows.append(training_speed(env_id, algo, fast_updates=fast, quick=quick))
                console.print(f"  {algo} {env_id} fast_updates={fast}: done")
    table = Table(title="training, updates included, per environment step (2 workers)")
    for col in ("run", "updates of", "steps/s", "CPU-bound steps/s", "learner CPU ms",
                "of which updates", "workers CPU ms", "load"):  # fmt: skip
        table.add_column(col, justify="right")
    for r in rows:
        table.add_row(
            f"{r['algo']} {r['env_id'].split('/')[-1]}",
            "Pliant" if r["fast_updates"] else "SB3",
            f"{r['steps_per_s']:.1f}",
            f"{r['cpu_bound_steps_per_s']:.1f}",
            f"{r['learner_cpu_ms_per_step']:.1f}",
            f"{r['update_cpu_ms_per_step']:.1f}",
            f"{r['workers_cpu_ms_per_step']:.1f}",
            f"{r['load_average']:.1f}",
        )
    console.print(table)
    write_json(out, {"training": rows, "quick": quick, "cpu_count": os.cpu_count()})
    console.print(f"saved {out}")
    return rows
