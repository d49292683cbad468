"""pliant.learn: learners against known answers (SB3's identity-test idea), exact resume,
behaviour cloning, robust workers, the command line, Ray.

The learners' tests run on ``pliant-test/PointReach-v0`` (pliant/learn/toys.py): a point on
[-1, 1] must reach a goal within 0.1 in at most 20 steps of at most 0.25 (reward: minus the
distance). Over 200 episodes a random policy's mean return is -11.1 and it succeeds in 50 %
of them; the optimal policy (``point_reach_expert``) returns -0.98 on average, -6.2 at worst,
and always succeeds.
"""

from __future__ import annotations

import json
import os
import signal
from functools import partial

import numpy as np
import pytest
import torch

from pliant.learn import TrainConfig, load_config, parameters, train
from pliant.learn.bc import agreement, behaviour_clone, collect_expert, predict_actions
from pliant.learn.evaluate import evaluate_saved, load_policy, run_episodes
from pliant.learn.toys import PointReachEnv, point_reach_expert
from pliant.learn.vec import make_env

TOY = "pliant-test/PointReach-v0"


@pytest.fixture(autouse=True)
def _one_thread():
    # Bit-exact comparisons need the same reductions in both runs; one thread also keeps the
    # tests from fighting over a small machine's cores.
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)


class _RandomPolicy:
    def __init__(self, space, seed=0):
        self.space = space
        self.space.seed(seed)

    def predict(self, obs, state=None, episode_start=None, deterministic=True):
        return self.space.sample(), None


def _random_return(episodes=50) -> float:
    env = make_env(TOY)
    return run_episodes(_RandomPolicy(env.action_space), env, episodes, seed=0).mean_return


def _config(algo: str, steps: int, **kw) -> TrainConfig:
    small = {"policy": "MlpPolicy", "policy_kwargs": {"net_arch": [64, 64]}}
    if algo == "SAC":
        small.update(learning_starts=200, batch_size=64)
    if algo == "PPO":
        small.update(n_steps=256, batch_size=64)
    defaults = dict(
        env_id=TOY,
        algo=algo,
        total_timesteps=steps,
        n_envs=1,
        vec_env="dummy",
        eval_freq=0,
        eval_episodes=30,
        checkpoint_freq=0,
        video_episodes=0,
        hyperparams=small,
    )
    defaults.update(kw)
    return TrainConfig(**defaults)


@pytest.mark.parametrize(("algo", "steps"), [("PPO", 6000), ("SAC", 3000)])
def test_learner_beats_random_policy(tmp_path, algo, steps):
    """A few thousand steps take the deterministic policy's mean return above -4 and its
    success rate above 80 %, where a random policy scores -11 and 50 %."""
    random_return = _random_return()
    assert random_return < -8.0
    result = train(_config(algo, steps), tmp_path / algo)
    final = result.summary["final_evaluation"]
    assert final["mean_return"] > -4.0, final
    assert final["success_rate"] > 0.8, final


@pytest.mark.parametrize("algo", ["PPO", "SAC"])
def test_the_final_evaluation_is_the_final_policys(tmp_path, algo):
    """A run whose last step is an evaluation step: its final evaluation is of the policy it
    saves (after the last update of the rollout, which follows the step), not of the one
    before it; the curve has one entry a step."""
    hyper = {"policy": "MlpPolicy", "policy_kwargs": {"net_arch": [16]}}
    if algo == "PPO":
        hyper.update(n_steps=100, batch_size=50)
    else:
        hyper.update(learning_starts=50, batch_size=32, train_freq=100, gradient_steps=20)
    config = _config(algo, 300, eval_freq=100, eval_episodes=3, seed=1, hyperparams=hyper)
    result = train(config, tmp_path / "run")
    final = result.summary["final_evaluation"]
    curve = json.loads((tmp_path / "run" / "evaluations.json").read_text())
    assert [e["step"] for e in curve] == [100, 200, 300] and final == curve[-1]
    again = evaluate_saved(tmp_path / "run" / "final", episodes=3, seed=10_000)
    assert again.to_dict() == {k: v for k, v in final.items() if k != "step"}


@pytest.mark.parametrize("algo", ["PPO", "SAC"])
def test_resume_after_interruption_gives_the_same_parameters(tmp_path, algo):
    """A run stopped after its checkpoint at step 300 and resumed ends with parameters equal,
    bit for bit, to those of an uninterrupted run (one environment, fixed seed); SAC's replay
    buffer (its gradient steps begin at 200), the normaliser and every random generator travel
    in the checkpoint."""
    from stable_baselines3.common.callbacks import BaseCallback

    class Interrupt(BaseCallback):
        def _on_step(self) -> bool:
            return self.num_timesteps < 400

    steps = 600
    cfg = partial(
        _config, algo, steps, checkpoint_freq=300, keep_checkpoints=10, normalize=True, seed=3,
        eval_episodes=2,
    )  # fmt: skip
    if algo == "PPO":
        cfg = partial(cfg, hyperparams={"policy": "MlpPolicy", "n_steps": 100, "batch_size": 50})
    whole = train(cfg(), tmp_path / "whole")
    cut = train(cfg(), tmp_path / "cut", extra_callbacks=[Interrupt()])
    assert cut.summary["steps"] < steps
    checkpoints = sorted(p.name for p in (tmp_path / "cut" / "checkpoints").iterdir())
    assert "step_300" in checkpoints and f"step_{steps}" not in checkpoints
    resumed = train(run_dir=tmp_path / "cut", resume=True)
    assert resumed.summary["resumed_from"] == 300 and resumed.summary["steps"] == steps
    a, b = parameters(whole.model), parameters(resumed.model)
    assert a.keys() == b.keys()
    for key in a:
        np.testing.assert_array_equal(a[key], b[key], err_msg=key)
    rms_a = whole.model.get_vec_normalize_env().obs_rms
    rms_b = resumed.model.get_vec_normalize_env().obs_rms
    np.testing.assert_array_equal(rms_a.mean, rms_b.mean)


@pytest.mark.parametrize(
    ("algo", "hyperparams"),
    [
        ("A2C", {"policy": "MlpPolicy"}),
        ("DQN", {"policy": "MlpPolicy", "learning_starts": 50, "batch_size": 32}),
        (
            "RecurrentPPO",
            {
                "policy": "MlpLstmPolicy",
                "n_steps": 64,
                "batch_size": 32,
                "policy_kwargs": {"lstm_hidden_size": 16, "net_arch": [16]},
            },
        ),
    ],
)
def test_other_algorithms_resume_exactly(tmp_path, algo, hyperparams):
    """The same exact resume for A2C, DQN (discrete actions) and RecurrentPPO (its LSTM states
    in flight travel in the checkpoint)."""
    from stable_baselines3.common.callbacks import BaseCallback

    class Interrupt(BaseCallback):
        def _on_step(self) -> bool:
            return self.num_timesteps < 260

    env_kwargs = {"action_type": "discrete"} if algo == "DQN" else {}
    cfg = partial(
        _config, algo, 320, checkpoint_freq=128, keep_checkpoints=10, seed=1,
        env_kwargs=env_kwargs, hyperparams=hyperparams, eval_episodes=2,
    )  # fmt: skip
    whole = train(cfg(), tmp_path / "whole")
    train(cfg(), tmp_path / "cut", extra_callbacks=[Interrupt()])
    resumed = train(run_dir=tmp_path / "cut", resume=True)
    assert 0 < resumed.summary["resumed_from"] < 260
    a, b = parameters(whole.model), parameters(resumed.model)
    for key in a:
        np.testing.assert_array_equal(a[key], b[key], err_msg=key)


@pytest.mark.parametrize("action_type", ["continuous", "discrete"])
def test_behaviour_cloning_reproduces_the_expert(action_type):
    """BC of the optimal PointReach expert onto a PPO policy: on the expert's own data, the
    cloned deterministic actions are within 0.1 of the expert's on average (continuous, actions
    in [-1, 1]) or equal in 95 % of the states (discrete, 3 actions; the misses sit at the
    stay/move boundary)."""
    from stable_baselines3 import PPO

    env = make_env(TOY, {"action_type": action_type})
    data = collect_expert(env, point_reach_expert, episodes=40)
    # Discrete moves of 0.25 land within 0.1 of the goal in 80 % of the cases at best.
    expert_success = data["successes"].mean()
    assert expert_success > (0.99 if action_type == "continuous" else 0.6)
    model = PPO("MlpPolicy", env, seed=0, policy_kwargs={"net_arch": [64, 64]})
    before = agreement(predict_actions(model.policy, data["observations"]), data["actions"])
    losses = behaviour_clone(
        model.policy, data["observations"], data["actions"], epochs=150, batch_size=64
    )
    assert losses[-1] < losses[0]
    after = agreement(predict_actions(model.policy, data["observations"]), data["actions"])
    if action_type == "continuous":
        assert after["action_mean_abs_error"] < 0.1 < before["action_mean_abs_error"]
    else:
        assert after["action_accuracy"] > 0.95 > before["action_accuracy"]
    cloned = run_episodes(model, env, 40, seed=0)
    assert cloned.success_rate >= expert_success - 0.1


def test_successful_episodes_keep_whole_episodes_of_the_expert():
    from pliant.learn.bc import successful_episodes

    data = {
        "observations": np.arange(7.0)[:, None],
        "actions": np.arange(7) * 10,
        "episode_starts": np.array([1, 0, 0, 1, 0, 1, 0], dtype=bool),
        "returns": np.array([1.0, 2.0, 3.0]),
        "successes": np.array([True, False, True]),
    }
    kept = successful_episodes(data)
    assert kept["observations"].ravel().tolist() == [0.0, 1.0, 2.0, 5.0, 6.0]
    assert kept["actions"].tolist() == [0, 10, 20, 50, 60]
    assert kept["episode_starts"].tolist() == [True, False, False, True, False]
    assert kept["returns"].tolist() == [1.0, 3.0] and kept["successes"].all()
    with pytest.raises(ValueError, match="none"):
        successful_episodes({**data, "successes": np.zeros(3, dtype=bool)})


def test_recurrent_cloning_loss_is_the_step_by_step_one():
    """The cloning loss of one episode from zero states, its LSTM run over the sequence in one
    call: the loss and gradients of sb3-contrib's step-by-step evaluation (reset at its start)."""
    import gymnasium as gym
    from sb3_contrib import RecurrentPPO
    from sb3_contrib.common.recurrent.type_aliases import RNNStates

    from pliant.learn.bc import _loss

    env = make_env(TOY)
    policy = RecurrentPPO("MlpLstmPolicy", env, policy_kwargs={"lstm_hidden_size": 16}).policy
    assert isinstance(env.action_space, gym.spaces.Box)
    obs, actions = torch.randn(9, *env.observation_space.shape), torch.rand(9, 1) - 0.5
    starts = torch.zeros(9)
    starts[0] = 1.0

    def gradients(loss):
        policy.zero_grad()
        loss.backward()
        return {k: p.grad.clone() for k, p in policy.named_parameters() if p.grad is not None}

    ours = _loss(policy, obs, actions, 1e-3, starts)
    zeros = torch.zeros(1, 1, 16)
    states = RNNStates((zeros, zeros), (zeros, zeros))
    _, log_prob, entropy = policy.evaluate_actions(obs, actions, states, starts)
    theirs = -log_prob.mean() - 1e-3 * entropy.mean()
    assert float(ours) == pytest.approx(float(theirs), rel=1e-6)
    a, b = gradients(ours), gradients(theirs)
    assert a.keys() == b.keys() and any("lstm_actor" in k for k in a)
    for key in a:
        torch.testing.assert_close(a[key], b[key], rtol=1e-5, atol=1e-7)


def test_bc_pretraining_through_train(tmp_path):
    cfg = _config(
        "PPO",
        256,
        bc={
            "expert": "pliant.learn.toys:point_reach_expert", "epochs": 300, "episodes": 40,
            "std": 0.2,
        },
    )  # fmt: skip
    train(cfg, tmp_path)
    report = json.loads((tmp_path / "bc.json").read_text())
    assert report["pairs"] > 50 and report["expert_success_rate"] == 1.0
    assert report["action_mean_abs_error"] < 0.15
    # the policy as cloned, before PPO, is kept, with the exploration asked for, and
    # evaluates (mean actions) as the expert does
    cloned = load_policy(tmp_path / "cloned")
    assert torch.allclose(cloned.model.policy.log_std.exp(), torch.tensor(0.2))
    assert evaluate_saved(tmp_path / "cloned", episodes=10).success_rate >= 0.9


@pytest.mark.parametrize(
    ("bc", "match"),
    [
        ({"expert": "pliant.learn.toys:point_reach_expert", "std": -0.1}, "bc.std"),
        ({"expert": "pliant.learn.toys:point_reach_expert", "epochs": 0}, "bc.epochs"),
        ({"expert": "point_reach_expert"}, "module:function"),
        ({"expert": "pliant.learn.toys:point_reach_expert", "sdt": 0.1}, "unknown bc"),
    ],
)
def test_bad_bc_settings_are_refused_before_training(bc, match):
    with pytest.raises(ValueError, match=match):
        _config("PPO", 256, bc=bc)


def test_set_exploration_refuses_what_it_cannot_set():
    from stable_baselines3 import DQN, PPO

    from pliant.learn.bc import set_exploration

    ppo = PPO("MlpPolicy", PointReachEnv(), n_steps=64, seed=0)
    set_exploration(ppo.policy, 0.3)
    assert torch.allclose(ppo.policy.log_std.exp(), torch.tensor(0.3))
    with pytest.raises(ValueError, match="positive"):
        set_exploration(ppo.policy, 0.0)
    dqn = DQN("MlpPolicy", PointReachEnv(action_type="discrete"), seed=0)
    with pytest.raises(ValueError, match="log_std"):
        set_exploration(dqn.policy, 0.3)


def test_dead_worker_is_restarted_and_training_goes_on(tmp_path):
    """Killing a SubprocVecEnv worker (SIGKILL) mid-run ends that worker's episode as truncated
    with info["worker_restarted"] and its last observation as terminal observation; a new
    worker takes its place and the run completes."""
    from stable_baselines3.common.callbacks import BaseCallback

    class KillOnce(BaseCallback):
        killed_pid, seen = None, []

        def _on_step(self) -> bool:
            venv = self.training_env
            if self.num_timesteps == 200:
                self.killed_pid = venv.processes[1].pid
                os.kill(self.killed_pid, signal.SIGKILL)
                venv.processes[1].join(timeout=10)
            elif self.killed_pid is not None and not self.seen:
                self.seen = list(zip(self.locals["dones"], self.locals["infos"], strict=True))
                self.new_pid = venv.processes[1].pid
            return True

    kill = KillOnce()
    result = train(
        _config("PPO", 512, n_envs=2, vec_env="subproc"), tmp_path, extra_callbacks=[kill]
    )
    assert result.summary["steps"] == 512 and result.summary["worker_restarts"] == 1
    (done0, info0), (done1, info1) = kill.seen
    assert done1 and info1["worker_restarted"] and info1["TimeLimit.truncated"]
    assert np.all(np.isfinite(info1["terminal_observation"]))
    assert not info0.get("worker_restarted") and kill.new_pid != kill.killed_pid


def test_diverged_episodes_are_counted(tmp_path):
    """Episodes truncated by a (simulated) divergence are counted (TensorBoard scalar
    robust/diverged_episodes, summary, episodes.csv) and no NaN reaches the learner."""
    cfg = _config("PPO", 512, env_kwargs={"diverge_probability": 0.05})
    result = train(cfg, tmp_path)
    assert result.summary["diverged_episodes"] > 0
    lines = (tmp_path / "episodes.csv").read_text().splitlines()[1:]
    assert sum(int(line.split(",")[-1]) for line in lines) == result.summary["diverged_episodes"]
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    events = EventAccumulator(str(next((tmp_path / "tb").iterdir()))).Reload()
    assert "robust/diverged_episodes" in events.Tags()["scalars"]
    assert all(np.isfinite(p).all() for p in parameters(result.model).values())


def test_configs_carry_the_thesis_networks(tmp_path):
    assert load_config("pliant/CartStemContact-v0", "SAC").hyperparams["policy_kwargs"] == {
        "net_arch": [512, 512, 512]
    }
    assert load_config("pliant/Multigait-v0", "PPO").hyperparams["policy_kwargs"] == {
        "net_arch": [256, 128, 64]
    }
    assert load_config("pliant/TrunkSpaceDebris-v0", "PPO").hyperparams["policy_kwargs"] == {
        "net_arch": [512, 512, 512]
    }
    gripper = load_config("pliant/Gripper-v0", "RecurrentPPO")
    assert gripper.hyperparams["policy_kwargs"]["lstm_hidden_size"] == 128
    user = tmp_path / "user.yaml"
    user.write_text("SAC:\n  n_envs: 4\n  hyperparams:\n    batch_size: 64\n")
    cfg = load_config("pliant/CartStemContact-v0", "SAC", user, {"seed": 7})
    assert (cfg.n_envs, cfg.seed, cfg.hyperparams["batch_size"]) == (4, 7, 64)
    assert cfg.hyperparams["policy_kwargs"]["net_arch"] == [512, 512, 512]
    user.write_text("learning_rate: 0.1\n")
    with pytest.raises(ValueError, match="hyperparams"):
        load_config(TOY, "PPO", user)


def test_cli_train_eval_enjoy_on_cartstem(tmp_path):
    """The verbs end to end on a real Pliant environment (its quick variant), tiny budget."""
    from typer.testing import CliRunner

    from pliant.cli import app

    runner = CliRunner()
    run = tmp_path / "run"
    base = ["train", "pliant/CartStemContact-v0", "--algo", "SAC", "--quick", "--n-envs", "1"]
    common = ["--eval-episodes", "2", "--checkpoint-freq", "100", "--no-progress"]
    args = [*base, "--steps", "150", "--out", str(run), *common, "--hyper", "learning_starts=50"]
    args += ["--hyper", "batch_size=32", "--video-episodes", "1"]
    result = runner.invoke(app, args)
    assert result.exit_code == 0, result.output
    assert (run / "final" / "model.zip").exists() and (run / "eval.gif").exists()
    assert (run / "checkpoints" / "step_150" / "replay_buffer.pkl").exists()
    result = runner.invoke(app, [*base, "--steps", "200", "--out", str(run), "--resume"])
    assert result.exit_code == 0, result.output
    assert json.loads((run / "summary.json").read_text())["steps"] == 200
    out = tmp_path / "eval.json"
    result = runner.invoke(app, ["eval", str(run), "--episodes", "2", "--json", str(out)])
    assert result.exit_code == 0, result.output
    evaluation = json.loads(out.read_text())
    assert evaluation["episodes"] == 2 and evaluation["success_rate"] is not None
    gif = tmp_path / "enjoy.gif"
    result = runner.invoke(app, ["enjoy", str(run / "final"), "--gif", str(gif)])
    assert result.exit_code == 0, result.output
    assert gif.stat().st_size > 0


def test_ray_actor_workers_and_tune_sweep(tmp_path):
    """Two Ray actor workers behind the VecEnv interface run a short PPO training; a Ray Tune
    trial is an ordinary training run in its own folder."""
    ray = pytest.importorskip("ray", reason="Ray is not installed (optional extra pliant[ray])")
    from pliant.learn.distributed import tune_sweep

    try:
        cfg = _config("PPO", 512, n_envs=2, vec_env="ray")
        result = train(cfg, tmp_path / "actors")
        assert result.summary["steps"] == 512
        sweep = tmp_path / "sweep.yaml"
        sweep.write_text(
            "algo: PPO\nmetric: mean_return\nsearch:\n  seed: {grid: [1]}\n"
            "base: {total_timesteps: 128, eval_episodes: 2, video_episodes: 0,"
            " hyperparams: {policy: MlpPolicy, n_steps: 64, batch_size: 32}}\n"
        )
        rows = tune_sweep(TOY, sweep, out=tmp_path / "tune")
        assert [(r["config"]["seed"], r["steps"]) for r in rows] == [(1, 128)]
        assert (tmp_path / "tune" / "seed=1" / "final" / "model.zip").exists()
    finally:
        ray.shutdown()
