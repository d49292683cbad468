"""The learner's cost per training step (`pliant bench --learner`): the arithmetic PyTorch's
FLOP counter counts scales as the network's, and the report says what it measured."""

from __future__ import annotations

import pytest

from pliant.bench.learner import bfloat16_speedup, learner_cost, training_speed
from pliant.errors import TrainingError

TOY = "pliant-test/PointReach-v0"  # pliant.learn.toys


def _cost(width: int):
    return learner_cost(
        "Pendulum-v1",  # SB3's defaults (configs/default.yaml), no simulation to build
        "SAC",
        env_steps=32,
        repeats=1,
        hyperparams={"batch_size": 64, "policy_kwargs": {"net_arch": [width] * 3}},
    )


def test_learner_arithmetic_scales_as_the_hidden_layers():
    """Three hidden layers of width h on 3 observations and 1 action: the two h x h products
    dominate every forward and backward pass, so doubling h multiplies the operations by
    (2 * 256^2 + 12 * 256) / (2 * 128^2 + 12 * 128) = 3.86 up to the small layers' share
    (the input and output layers' exact count differs between actor and critics)."""
    small, large = _cost(128), _cost(256)
    ratio = large.gflop_per_env_step / small.gflop_per_env_step
    assert 3.5 < ratio < 4.1, ratio
    for cost in (small, large):
        assert cost.ms_per_env_step > 0.0 and cost.matmul_gflop_per_s > 0.0
        assert cost.learner_bound_steps_per_s == pytest.approx(1e3 / cost.ms_per_env_step)
        assert cost.net_arch == [cost.net_arch[0]] * 3 and cost.torch_threads == 1


def test_learner_cost_refuses_empty_runs_unknown_algorithms_and_environments():
    with pytest.raises(TrainingError, match="env_steps"):
        learner_cost("Pendulum-v1", "SAC", env_steps=0)
    with pytest.raises(TrainingError, match="algo must be one of"):
        learner_cost("Pendulum-v1", "XYZ")
    with pytest.raises(TrainingError, match="no environment 'pliant/NoSuch-v0'"):
        learner_cost("pliant/NoSuch-v0", "SAC")


def test_bfloat16_speedup_reports_both_speeds_and_the_cpu():
    """Whether bfloat16 pays depends on the CPU (AVX512-BF16 or not): the bench measures it."""
    report = bfloat16_speedup(repeats=1)
    assert report["matmul_fp32_gflop_per_s"] > 0.0 and report["matmul_bf16_gflop_per_s"] > 0.0
    assert report["bf16_over_fp32"] == pytest.approx(
        report["matmul_bf16_gflop_per_s"] / report["matmul_fp32_gflop_per_s"]
    )
    assert report["cpu_capability"]


def test_training_speed_times_the_window_after_the_warm_up():
    """`pliant bench --training` on the toy task (one environment, in this process, small
    networks): SAC's window starts after learning_starts and holds one update per step;
    PPO's is one rollout and its update."""
    small = {"policy": "MlpPolicy", "policy_kwargs": {"net_arch": [32, 32]}}
    one = {"n_envs": 1, "vec_env": "dummy"}
    sac = training_speed(TOY, "SAC", window=24, overrides={**one, "hyperparams": small})
    assert (sac["window_steps"], sac["updates"], sac["warmup_steps"]) == (24, 24, 100)
    ppo = training_speed(TOY, "PPO", quick=True, overrides={**one, "hyperparams": small})
    assert (ppo["window_steps"], ppo["updates"], ppo["warmup_steps"]) == (256, 1, 0)
    for r in (sac, ppo):
        assert r["fast_updates"] and r["steps_per_s"] > 0.0
        assert 0.0 < r["update_cpu_ms_per_step"] <= r["learner_cpu_ms_per_step"]
        assert r["workers_cpu_ms_per_step"] == 0.0  # no worker process
        assert r["cpu_bound_steps_per_s"] == pytest.approx(1e3 / r["learner_cpu_ms_per_step"])
