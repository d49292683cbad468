"""A compact soft actor-critic (Haarnoja et al. 2018; thesis [KG17]) and its replay buffer.

Actions are tanh-squashed Gaussians in [-1, 1]^m (the caller scales them to the action
space); twin Q-functions with Polyak-averaged targets; the entropy temperature is tuned to
the target entropy -m. :meth:`SAC.update` takes the bootstrap value of the next state from
the caller when given: the internal agents of the graph borrow it from a neighbour node's
critic at boundary states (thesis L821).
"""

from __future__ import annotations

import numpy as np
import torch
from torch import nn
from torch.nn import functional as F

LOG_STD_MIN, LOG_STD_MAX = -5.0, 2.0


def mlp(inputs: int, outputs: int, hidden: int, layers: int = 3) -> nn.Sequential:
    """``layers`` hidden layers of ``hidden`` units with ReLU (D.2: all the authors' MLPs)."""
    sizes = [inputs] + [hidden] * layers
    modules: list[nn.Module] = []
    for a, b in zip(sizes[:-1], sizes[1:], strict=True):
        modules += [nn.Linear(a, b), nn.ReLU()]
    modules.append(nn.Linear(sizes[-1], outputs))
    return nn.Sequential(*modules)


@torch.no_grad()
def polyak(net: nn.Module, target: nn.Module, tau: float) -> None:
    """target <- (1 − τ) target + τ net."""
    for p, p_target in zip(net.parameters(), target.parameters(), strict=True):
        p_target.lerp_(p, tau)


class ReplayBuffer:
    """A ring buffer of named fields, each an array with a fixed per-item shape."""

    def __init__(self, capacity: int, **shapes: tuple[int, ...]) -> None:
        self.capacity = int(capacity)
        self.data = {k: np.zeros((self.capacity, *s), dtype=np.float32) for k, s in shapes.items()}
        self.size = 0
        self.next = 0

    def __len__(self) -> int:
        return self.size

    def add(self, **item) -> None:
        for key, array in self.data.items():
            array[self.next] = item[key]
        self.next = (self.next + 1) % self.capacity
        self.size = min(self.size + 1, self.capacity)

    def sample(self, n: int, rng: np.random.Generator) -> dict[str, torch.Tensor]:
        index = rng.integers(0, self.size, size=n)
        return {k: torch.as_tensor(v[index]) for k, v in self.data.items()}

    def state_dict(self) -> dict:
        return {"data": {k: v[: self.size].copy() for k, v in self.data.items()}, "next": self.next}

    def load_state_dict(self, state: dict) -> None:
        for key, values in state["data"].items():
            self.data[key][: len(values)] = values
        self.size = len(next(iter(state["data"].values())))
        self.next = state["next"]


class SAC(nn.Module):
    """Soft actor-critic on observations of size ``obs_dim``, actions in [-1, 1]^act_dim."""

    def __init__(
        self,
        obs_dim: int,
        act_dim: int,
        *,
        hidden: int = 256,
        lr: float = 3e-4,
        gamma: float = 0.99,
        tau: float = 5e-3,
        init_alpha: float = 0.1,
    ) -> None:
        super().__init__()
        self.act_dim, self.gamma, self.tau = act_dim, gamma, tau
        self.actor = mlp(obs_dim, 2 * act_dim, hidden)
        self.q = nn.ModuleList(mlp(obs_dim + act_dim, 1, hidden) for _ in range(2))
        self.q_target = nn.ModuleList(mlp(obs_dim + act_dim, 1, hidden) for _ in range(2))
        self.q_target.load_state_dict(self.q.state_dict())
        self.q_target.requires_grad_(False)
        self.log_alpha = nn.Parameter(torch.tensor(float(np.log(init_alpha))))
        self.target_entropy = -float(act_dim)
        self.actor_opt = torch.optim.Adam(self.actor.parameters(), lr=lr)
        self.q_opt = torch.optim.Adam(self.q.parameters(), lr=lr)
        self.alpha_opt = torch.optim.Adam([self.log_alpha], lr=lr)

    def checkpoint(self) -> dict:
        """Parameters and optimiser states (resuming continues the same Adam moments)."""
        optimisers = (self.actor_opt, self.q_opt, self.alpha_opt)
        return {"net": self.state_dict(), "opt": [o.state_dict() for o in optimisers]}

    def restore(self, checkpoint: dict) -> None:
        self.load_state_dict(checkpoint["net"])
        for o, saved in zip(
            (self.actor_opt, self.q_opt, self.alpha_opt), checkpoint["opt"], strict=True
        ):
            o.load_state_dict(saved)

    @property
    def alpha(self) -> torch.Tensor:
        return self.log_alpha.exp().detach()

    def policy(self, obs: torch.Tensor, deterministic: bool = False):
        """(action, log-probability) of the tanh-Gaussian policy."""
        mean, log_std = self.actor(obs).chunk(2, dim=-1)
        std = log_std.clamp(LOG_STD_MIN, LOG_STD_MAX).exp()
        u = mean if deterministic else mean + std * torch.randn_like(mean)
        action = torch.tanh(u)
        # log N(u) - Σ log(1 - tanh(u)²), the latter written stably.
        logp = torch.distributions.Normal(mean, std).log_prob(u).sum(-1)
        logp = logp - (2.0 * (np.log(2.0) - u - F.softplus(-2.0 * u))).sum(-1)
        return action, logp

    @torch.no_grad()
    def act(self, obs: np.ndarray, deterministic: bool = False) -> np.ndarray:
        obs_t = torch.as_tensor(np.asarray(obs, dtype=np.float32))
        return self.policy(obs_t, deterministic)[0].numpy()

    def q_values(self, obs: torch.Tensor, action: torch.Tensor, target: bool = False):
        x = torch.cat([obs, action], dim=-1)
        nets = self.q_target if target else self.q
        return [net(x).squeeze(-1) for net in nets]

    @torch.no_grad()
    def soft_value(self, obs: torch.Tensor) -> torch.Tensor:
        """V(s) = E_a~π [min_k Q_target,k(s, a) − α log π(a|s)], one sample."""
        action, logp = self.policy(obs)
        return torch.minimum(*self.q_values(obs, action, target=True)) - self.alpha * logp

    def update(
        self,
        obs: torch.Tensor,
        action: torch.Tensor,
        reward: torch.Tensor,
        next_obs: torch.Tensor,
        done: torch.Tensor,
        next_value: torch.Tensor | None = None,
        duration: torch.Tensor | None = None,
    ) -> dict[str, float]:
        """One gradient step. Target y = r + γ^duration (1 − done) V(s'), V(s') from this
        agent's critic unless ``next_value`` is given."""
        if next_value is None:
            next_value = self.soft_value(next_obs)
        discount = self.gamma if duration is None else self.gamma**duration
        y = reward + discount * (1.0 - done) * next_value
        q1, q2 = self.q_values(obs, action)
        q_loss = F.mse_loss(q1, y) + F.mse_loss(q2, y)
        self.q_opt.zero_grad()
        q_loss.backward()
        self.q_opt.step()

        new_action, logp = self.policy(obs)
        q_pi = torch.minimum(*self.q_values(obs, new_action))
        actor_loss = (self.alpha * logp - q_pi).mean()
        self.actor_opt.zero_grad()
        actor_loss.backward()
        self.actor_opt.step()
        self.q.zero_grad()

        alpha_loss = -(self.log_alpha * (logp.detach() + self.target_entropy)).mean()
        self.alpha_opt.zero_grad()
        alpha_loss.backward()
        self.alpha_opt.step()

        polyak(self.q, self.q_target, self.tau)
        return {"q_loss": q_loss.item(), "actor_loss": actor_loss.item()}
