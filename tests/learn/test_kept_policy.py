"""pliant.learn.kept: a kept policy acts as the Stable-Baselines3 model it was exported from
(the same deterministic actions, the same samples under the same torch seed), behind the same
observation normaliser; it is small; a damaged file or a wrong observation is a typed error.

The models are untrained (random weights, a random log standard deviation and random
normaliser statistics): what is tested is the arithmetic of acting, not a learner.
"""

from __future__ import annotations

import json

import gymnasium as gym
import numpy as np
import pytest
import torch
from stable_baselines3 import DQN, PPO, SAC, TD3
from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize
from typer.testing import CliRunner

from pliant.cli import app
from pliant.errors import CorruptFileError, PolicyError
from pliant.learn.evaluate import (
    evaluate_saved,
    export_run,
    load_policy,
    run_episodes,
    save_policy,
)
from pliant.learn.kept import KeptPolicy, export_policy
from pliant.learn.kept import load_policy as load_kept
from pliant.learn.toys import PointReachEnv
from pliant.learn.vec import make_env

TOY = "pliant-test/PointReach-v0"


class _Spaces(gym.Env):
    """An environment that only has spaces (the models are never trained)."""

    def __init__(self, observation_space, action_space) -> None:
        self.observation_space, self.action_space = observation_space, action_space

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        return self.observation_space.sample(), {}

    def step(self, action):
        return self.observation_space.sample(), 0.0, False, False, {}


BOX_OBS = gym.spaces.Box(-2.0, 3.0, (6,), np.float32)
BOX_ACT = gym.spaces.Box(
    np.array([-1.0, 0.0, -0.5], np.float32), np.array([1.0, 2.0, 0.5], np.float32)
)


def _normalizer(env, rng) -> VecNormalize:
    venv = VecNormalize(DummyVecEnv([lambda: env]), clip_obs=2.5)
    venv.obs_rms.mean = rng.normal(size=env.observation_space.shape)
    venv.obs_rms.var = rng.uniform(0.2, 3.0, size=env.observation_space.shape)
    venv.training = False
    return venv


def _model(algo: str, action_space, normalize: bool):
    torch.manual_seed(3)
    env = _Spaces(BOX_OBS, action_space)
    kwargs = {"policy_kwargs": {"net_arch": [16, 8], "activation_fn": torch.nn.Tanh}}
    if algo in ("SAC", "TD3", "DQN"):
        kwargs.update(buffer_size=10, learning_starts=0)
    model = {"PPO": PPO, "SAC": SAC, "TD3": TD3, "DQN": DQN}[algo]("MlpPolicy", env, **kwargs)
    if algo == "PPO" and isinstance(action_space, gym.spaces.Box):
        with torch.no_grad():  # not SB3's 0: a log std that moves the samples
            model.policy.log_std.copy_(torch.tensor([-0.5, 0.3, 0.1]))
    vecnorm = _normalizer(env, np.random.default_rng(1)) if normalize else None
    return model, vecnorm


CASES = [
    ("PPO", BOX_ACT, True),
    ("PPO", BOX_ACT, False),
    ("PPO", gym.spaces.Discrete(5), True),
    ("SAC", BOX_ACT, True),
    ("SAC", BOX_ACT, False),
    ("TD3", BOX_ACT, True),
    ("DQN", gym.spaces.Discrete(4), False),
]


@pytest.mark.parametrize(("algo", "action_space", "normalize"), CASES)
def test_kept_policy_acts_as_the_sb3_model(tmp_path, algo, action_space, normalize):
    model, vecnorm = _model(algo, action_space, normalize)
    path = export_policy(model, tmp_path / "policy.npz", vecnormalize=vecnorm)
    kept = load_kept(path)
    assert isinstance(kept, KeptPolicy) and kept.algo == algo
    raw = np.random.default_rng(0).uniform(-4, 4, size=(64, 6)).astype(np.float32)
    seen = vecnorm.normalize_obs(raw) if vecnorm is not None else raw
    expected, _ = model.predict(seen, deterministic=True)
    actions, state = kept.predict(raw, deterministic=True)
    assert state is None and actions.dtype == expected.dtype
    np.testing.assert_array_equal(actions, expected)
    single, _ = kept.predict(raw[7])  # one observation: no batch axis, as SB3
    np.testing.assert_array_equal(single, model.predict(seen[7], deterministic=True)[0])
    if algo != "DQN":  # sampled actions: the same draws under the same torch seed
        torch.manual_seed(11)
        expected, _ = model.predict(seen, deterministic=False)
        torch.manual_seed(11)
        np.testing.assert_array_equal(kept.predict(raw, deterministic=False)[0], expected)
        if algo in ("PPO", "SAC") and isinstance(action_space, gym.spaces.Box):
            assert np.ptp(expected[:, 0]) > 0.1  # the draws differ: a real distribution


def _recurrent(action_space, normalize: bool, layers: int = 1):
    from sb3_contrib import RecurrentPPO

    torch.manual_seed(5)
    env = _Spaces(BOX_OBS, action_space)
    kwargs = {"net_arch": [16], "lstm_hidden_size": 12, "n_lstm_layers": layers}
    model = RecurrentPPO("MlpLstmPolicy", env, policy_kwargs=kwargs, n_steps=8, batch_size=8)
    if isinstance(action_space, gym.spaces.Box):
        with torch.no_grad():
            model.policy.log_std.copy_(torch.tensor([-0.5, 0.3, 0.1]))
    vecnorm = _normalizer(env, np.random.default_rng(4)) if normalize else None
    return model, vecnorm


@pytest.mark.parametrize(
    ("action_space", "normalize", "layers"),
    [(BOX_ACT, True, 1), (BOX_ACT, False, 2), (gym.spaces.Discrete(5), True, 1)],
)
def test_a_kept_recurrent_policy_acts_as_the_sb3_model(tmp_path, action_space, normalize, layers):
    """RecurrentPPO: the actor's LSTM carried from step to step and reset where an episode
    starts, for a batch of environments: the same actions and states as its ``predict``."""
    model, vecnorm = _recurrent(action_space, normalize, layers)
    kept = load_kept(export_policy(model, tmp_path / "lstm.npz", vecnormalize=vecnorm))
    assert kept.algo == "RecurrentPPO" and kept.meta["version"] == 2
    rng = np.random.default_rng(0)
    ours = theirs = None
    for t in range(6):  # 4 environments; the second and the last restart at steps 3 and 4
        raw = rng.uniform(-4, 4, size=(4, 6)).astype(np.float32)
        seen = vecnorm.normalize_obs(raw) if vecnorm is not None else raw
        start = np.array([t == 0, t in (0, 3), t == 0, t in (0, 4)])
        expected, theirs = model.predict(seen, theirs, start, deterministic=True)
        actions, ours = kept.predict(raw, ours, start, deterministic=True)
        np.testing.assert_array_equal(actions, expected)
        for a, b in zip(ours, theirs, strict=True):
            np.testing.assert_allclose(a, b, rtol=0, atol=1e-6)
    assert np.abs(ours[0]).max() > 1e-3  # a state that carries something
    torch.manual_seed(2)
    sampled, _ = model.predict(seen, theirs, None, deterministic=False)
    torch.manual_seed(2)
    np.testing.assert_array_equal(kept.predict(raw, ours, None, deterministic=False)[0], sampled)
    single, state = kept.predict(raw[0])  # one observation, a fresh state
    assert state[0].shape == (layers, 1, 12)
    first, _ = model.predict(seen[0], None, np.array([True]), deterministic=True)
    np.testing.assert_array_equal(single, first)
    with pytest.raises(PolicyError, match="LSTM state"):
        kept.predict(raw, (ours[0][:, :2], ours[1][:, :2]))
    with pytest.raises(PolicyError, match="3 episode_start flag"):
        kept.predict(raw, ours, np.ones(3, dtype=bool))


def test_a_kept_recurrent_policy_evaluates_as_its_saved_run(tmp_path):
    """Episodes on an environment (the LSTM reset at each): the same returns as the run's own
    RecurrentPPO through ``pliant.learn.evaluate``."""
    from sb3_contrib import RecurrentPPO

    env = make_env(TOY)
    kwargs = {"net_arch": [16], "lstm_hidden_size": 8}
    model = RecurrentPPO("MlpLstmPolicy", env, policy_kwargs=kwargs, seed=0)
    save_policy(model, tmp_path / "final", "RecurrentPPO", TOY, {}, None)
    export_run(tmp_path / "final", tmp_path / "kept.npz")
    kept, saved = load_policy(tmp_path / "kept.npz"), load_policy(tmp_path / "final")
    ours = run_episodes(kept.model, env, 3, seed=5)
    theirs = run_episodes(saved.model, env, 3, seed=5)
    assert ours.returns == theirs.returns and ours.mean_length > 1


def test_a_3x512_ppo_actor_is_small(tmp_path):
    env = _Spaces(gym.spaces.Box(-1, 1, (48,), np.float32), BOX_ACT)
    arch = {"net_arch": {"pi": [512, 512, 512], "vf": [512, 512, 512]}}
    model = PPO("MlpPolicy", env, policy_kwargs=arch)
    path = export_policy(model, tmp_path / "policy.npz", provenance={"step": 0})
    model.save(tmp_path / "model.zip")
    size = path.stat().st_size
    assert size < 2.5e6
    # the critic and the optimiser's state left out (an untrained model.zip compresses its
    # zero Adam moments: a trained one is about 13 MB)
    assert size < 0.5 * (tmp_path / "model.zip").stat().st_size


@pytest.fixture(scope="module")
def kept_file(tmp_path_factory):
    model, vecnorm = _model("PPO", BOX_ACT, True)
    return export_policy(
        model, tmp_path_factory.mktemp("kept") / "policy.npz", vecnormalize=vecnorm
    )


def test_damaged_kept_files_are_corrupt_file_errors(tmp_path, kept_file):
    data = kept_file.read_bytes()
    truncated = tmp_path / "truncated.npz"
    truncated.write_bytes(data[: len(data) // 2])
    flipped = tmp_path / "flipped.npz"
    flipped.write_bytes(data[:200] + bytes([data[200] ^ 0xFF]) + data[201:])
    empty = tmp_path / "empty.npz"
    empty.write_bytes(b"")
    text = tmp_path / "text.npz"
    text.write_text("not a policy")
    other = tmp_path / "other.npz"
    np.savez(other, meta=np.frombuffer(json.dumps({"format": "x"}).encode(), np.uint8))
    for path in (truncated, flipped, empty, text, other):
        with pytest.raises(CorruptFileError) as error:
            load_kept(path)
        assert error.value.path == path and str(path) in str(error.value)


def test_wrong_observations_are_policy_errors(kept_file):
    kept = load_kept(kept_file)
    with pytest.raises(PolicyError, match=r"shape \(5,\).*\(6,\)"):
        kept.predict(np.zeros(5))
    with pytest.raises(PolicyError, match="NaN"):
        kept.predict(np.full(6, np.nan))


def test_unsupported_policies_are_refused(tmp_path):
    env = _Spaces(BOX_OBS, BOX_ACT)
    with pytest.raises(PolicyError, match="gSDE"):
        export_policy(PPO("MlpPolicy", env, use_sde=True), tmp_path / "sde.npz")
    assert not (tmp_path / "sde.npz").exists()


def test_a_kept_policy_evaluates_as_its_saved_run(tmp_path):
    """save_policy's folder (model.zip, vecnormalize.pkl, meta.json) kept by `pliant
    export-policy`: `load_policy` of the kept file gives the same episodes."""
    env = make_env(TOY)
    model = PPO("MlpPolicy", env, policy_kwargs={"net_arch": [16]}, seed=0)
    vecnorm = _normalizer(PointReachEnv(), np.random.default_rng(2))
    save_policy(model, tmp_path / "final", "PPO", TOY, {}, vecnorm)
    result = CliRunner().invoke(
        app, ["export-policy", str(tmp_path / "final"), str(tmp_path / "k")]
    )
    assert result.exit_code == 0, result.output
    kept = load_policy(tmp_path / "k.npz")
    assert (kept.algo, kept.env_id) == ("PPO", TOY)
    assert kept.model.policy.provenance["source"] == str(tmp_path / "final")
    saved = load_policy(tmp_path / "final")
    ours = run_episodes(kept.model, env, 3, normalize_obs=kept.normalize_obs, seed=5)
    theirs = run_episodes(saved.model, env, 3, normalize_obs=saved.normalize_obs, seed=5)
    assert ours.returns == theirs.returns
    (tmp_path / "k.npz").rename(tmp_path / "final" / "policy.npz")
    (tmp_path / "final" / "model.zip").unlink()  # a folder holding only the kept policy
    assert load_policy(tmp_path / "final").algo == "PPO"
    with pytest.raises(PolicyError, match="not SAC"):
        load_policy(tmp_path / "final", algo="SAC")
    with pytest.raises(PolicyError, match="kept policy already"):
        export_run(tmp_path / "final", tmp_path / "again.npz")


def test_sampled_episodes_of_a_kept_policy_are_its_saved_models(tmp_path):
    """`action_seed`: a SAC model and its kept actor, acting by sampling, draw the same actions
    (an SB3 model's loading draws from torch's generator; the seed is set after it)."""
    env = make_env(TOY)
    model = SAC("MlpPolicy", env, policy_kwargs={"net_arch": [16]}, seed=0, learning_starts=0)
    save_policy(model, tmp_path / "final", "SAC", TOY, {}, None)
    export_run(tmp_path / "final", tmp_path / "kept.npz")
    runs = [
        evaluate_saved(path, episodes=3, seed=5, deterministic=False, action_seed=7)
        for path in (tmp_path / "final", tmp_path / "kept.npz", tmp_path / "kept.npz")
    ]
    assert runs[0].returns == runs[1].returns == runs[2].returns
    other = evaluate_saved(tmp_path / "kept.npz", episodes=3, seed=5, deterministic=False)
    assert other.returns != runs[0].returns  # the draws depend on the seed


def test_layers_are_kept_by_name_only_with_their_default_arguments(tmp_path):
    env = _Spaces(BOX_OBS, BOX_ACT)
    silu = {"net_arch": [8], "activation_fn": torch.nn.SiLU}
    model = PPO("MlpPolicy", env, policy_kwargs=silu)
    assert load_kept(export_policy(model, tmp_path / "silu.npz")).meta["layers"]["trunk"] == [
        "linear",
        "SiLU",
    ]
    model.policy.mlp_extractor.policy_net[1] = torch.nn.LeakyReLU(0.3)
    with pytest.raises(PolicyError, match="LeakyReLU"):
        export_policy(model, tmp_path / "leaky.npz")
