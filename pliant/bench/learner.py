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
"""

from __future__ import annotations

import statistics
import time
from dataclasses import asdict, dataclass

import gymnasium as gym
import numpy as np

import pliant.envs  # noqa: F401  (registers the pliant/ ids with Gymnasium)
from pliant.errors import TrainingError
from pliant.learn.config import ALGOS, OFF_POLICY, load_config, sb3_kwargs
from pliant.learn.evaluate import algorithm_class


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
        kwargs = sb3_kwargs(params)
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
