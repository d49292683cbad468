"""The learner's updates without the time that is not their arithmetic: what `pliant train` sets
unless the configuration says ``fast_updates: false`` (:func:`fast_update_kwargs`).

**SAC's critics.**
Stable-Baselines3's SAC update back-propagates the actor's loss through both critics, and
PyTorch then computes the gradient of that loss with respect to every critic weight as well as
to the actions: one 256 x 512 by 512 x 512 product per hidden layer and critic, 4 of the 36
products of an update with the thesis' 3 x 512 networks (11 % of its arithmetic). Those weight
gradients are never used: the critic's optimizer clears them (``zero_grad``) before its next
backward pass, and nothing reads them in between. :class:`SACMlpPolicy` is SB3's ``MlpPolicy``
whose critics skip them. The updates are the same to the bit (the parameters after any number
of updates equal those of SB3's own policy, tests/learn/test_learner_updates.py).

**Fused Adam.** The algorithms whose optimizer is Adam (SB3's default for all but A2C) get
PyTorch's fused Adam (``fused=True``): one kernel over all parameters instead of a sequence of
element-wise passes over them, 6 % of a SAC update of the 3 x 512 networks. Its arithmetic is
Adam's, in another order of the floating-point operations: parameters differ from the unfused
optimizer's by round-off (relative 4e-6 after 300 SAC updates on Pendulum), not by method.

Measured on the thesis' SAC update (CartStemContact, 3 x 512, batch 256, one PyTorch thread,
medians of CPU time interleaved in one process on a shared 2-core host): 79.0 ms stock, 71.7 ms
with the critics above, 74.6 ms fused, 66.9 ms both (docs/concepts/speed.md, "The learner").
"""

from __future__ import annotations

import torch
from stable_baselines3.common.policies import ContinuousCritic
from stable_baselines3.sac.policies import SACPolicy


class ActionGradientCritic(ContinuousCritic):
    """SB3's twin critic. Called on actions that carry a gradient (the actor's loss, where the
    actions are the actor's), it treats its weights as constants: the graph it records leads
    to the actions only, so the backward pass skips the weight gradients nobody reads."""

    def forward(self, obs: torch.Tensor, actions: torch.Tensor) -> tuple[torch.Tensor, ...]:
        if not (actions.requires_grad and torch.is_grad_enabled()):
            return super().forward(obs, actions)
        # A node of the graph records, when it is built, which inputs need a gradient: the
        # weights are constants for this graph, whatever their flag is later.
        weights = [p for p in self.parameters() if p.requires_grad]
        for p in weights:
            p.requires_grad_(False)
        try:
            return super().forward(obs, actions)
        finally:
            for p in weights:
                p.requires_grad_(True)


class SACMlpPolicy(SACPolicy):
    """SB3's SAC ``MlpPolicy`` with :class:`ActionGradientCritic` critics (module docstring)."""

    def make_critic(self, features_extractor=None) -> ContinuousCritic:
        critic_kwargs = self._update_features_extractor(self.critic_kwargs, features_extractor)
        return ActionGradientCritic(**critic_kwargs).to(self.device)


# SB3 algorithms whose policies' optimizer is Adam unless the configuration names another one
# (A2C's is RMSprop, whose keywords A2C sets itself).
ADAM_ALGOS = ("PPO", "SAC", "TD3", "DQN", "RecurrentPPO")


def fast_update_kwargs(algo: str, kwargs: dict) -> dict:
    """SB3 constructor arguments `kwargs` (:func:`pliant.learn.config.sb3_kwargs`'s) of `algo`
    with the settings of the module docstring, where the configuration leaves them open: SAC's
    ``MlpPolicy`` becomes :class:`SACMlpPolicy`; Adam, named or by default, gets
    ``fused=True`` unless ``optimizer_kwargs`` say ``fused`` or ``foreach``."""
    out = dict(kwargs)
    if algo == "SAC" and out.get("policy") == "MlpPolicy":
        out["policy"] = SACMlpPolicy
    policy_kwargs = dict(out.get("policy_kwargs") or {})
    optimizer = policy_kwargs.get("optimizer_class", torch.optim.Adam)
    options = dict(policy_kwargs.get("optimizer_kwargs") or {})
    if (
        algo in ADAM_ALGOS
        and optimizer is torch.optim.Adam
        and not {"fused", "foreach"} & set(options)
    ):
        policy_kwargs["optimizer_kwargs"] = {**options, "fused": True}
        out["policy_kwargs"] = policy_kwargs
    return out


__all__ = ["ADAM_ALGOS", "ActionGradientCritic", "SACMlpPolicy", "fast_update_kwargs"]
