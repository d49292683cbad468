"""`pliant train`'s learner settings (pliant.learn.updates): SAC's critics skip the weight
gradients of the actor's loss without changing an update, Adam is fused, and a configuration
can ask for SB3's own updates."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from stable_baselines3 import SAC

from pliant.learn.config import TrainConfig
from pliant.learn.training import parameters, train
from pliant.learn.updates import ActionGradientCritic, SACMlpPolicy, fast_update_kwargs

TOY = "pliant-test/PointReach-v0"  # pliant.learn.toys


def _sac(policy, steps: int = 230, **policy_kwargs) -> SAC:
    model = SAC(
        policy, "Pendulum-v1", seed=0, learning_starts=200, batch_size=32, device="cpu",
        policy_kwargs={"net_arch": [32, 32], **policy_kwargs},
    )  # fmt: skip
    model.learn(steps)
    return model


def test_sac_critics_without_weight_gradients_update_to_the_bit():
    """30 updates with SACMlpPolicy's critics leave every parameter (actor, critics, targets)
    equal to the bit to those of SB3's MlpPolicy, same seed."""
    stock, fast = _sac("MlpPolicy"), _sac(SACMlpPolicy)
    assert isinstance(fast.critic, ActionGradientCritic)
    a, b = parameters(stock), parameters(fast)
    assert a.keys() == b.keys()
    for key in a:
        np.testing.assert_array_equal(a[key], b[key], err_msg=key)


def test_actor_loss_leaves_critic_weights_without_gradient():
    """Through the critics on actions that carry a gradient, the actions get one and the
    critic's weights none (their flags restored); on plain actions the weights get theirs."""
    critic = _sac(SACMlpPolicy, steps=1).critic
    obs = torch.zeros(4, 3)
    actions = torch.zeros(4, 1, requires_grad=True)
    sum(q.sum() for q in critic(obs, actions)).backward()
    assert actions.grad is not None and actions.grad.abs().sum() > 0
    assert all(p.grad is None and p.requires_grad for p in critic.parameters())
    sum(q.sum() for q in critic(obs, actions.detach())).backward()
    assert all(p.grad is not None for p in critic.parameters())


def test_fast_update_kwargs_leave_chosen_settings_alone():
    sac = fast_update_kwargs("SAC", {"policy": "MlpPolicy", "policy_kwargs": {"net_arch": [8]}})
    assert sac["policy"] is SACMlpPolicy
    assert sac["policy_kwargs"] == {"net_arch": [8], "optimizer_kwargs": {"fused": True}}
    assert fast_update_kwargs("SAC", {"policy": "CnnPolicy"})["policy"] == "CnnPolicy"
    assert "policy_kwargs" not in fast_update_kwargs("A2C", {"policy": "MlpPolicy"})
    chosen = {"policy": "MlpPolicy", "policy_kwargs": {"optimizer_kwargs": {"foreach": False}}}
    assert fast_update_kwargs("PPO", chosen) == chosen
    other = {"policy": "MlpPolicy", "policy_kwargs": {"optimizer_class": torch.optim.SGD}}
    assert fast_update_kwargs("TD3", other) == other


def _tiny(algo: str, **kw) -> TrainConfig:
    hyper = {"policy": "MlpPolicy", "policy_kwargs": {"net_arch": [16]}}
    hyper.update(
        {"SAC": {"learning_starts": 16, "batch_size": 8}}.get(
            algo, {"n_steps": 16, "batch_size": 16}
        )
    )
    return TrainConfig(
        env_id=TOY, algo=algo, total_timesteps=32, n_envs=1, vec_env="dummy", eval_freq=0,
        checkpoint_freq=0, video_episodes=0, hyperparams=hyper, **kw,
    )  # fmt: skip


@pytest.mark.parametrize("algo", ["SAC", "PPO"])
def test_train_applies_the_fast_updates_unless_told_not_to(tmp_path, algo):
    fast = train(_tiny(algo), tmp_path / "fast").model
    stock = train(_tiny(algo, fast_updates=False), tmp_path / "stock").model
    optimizer = fast.actor.optimizer if algo == "SAC" else fast.policy.optimizer
    assert optimizer.defaults["fused"] is True
    assert isinstance(fast.policy, SACMlpPolicy) == (algo == "SAC")
    assert not isinstance(stock.policy, SACMlpPolicy)
    optimizer = stock.actor.optimizer if algo == "SAC" else stock.policy.optimizer
    assert not optimizer.defaults["fused"]
