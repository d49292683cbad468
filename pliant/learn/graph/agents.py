"""The agents of the configuration-space graph (thesis §4.2.1, Fig. 4.7; D.1, D.2).

* :class:`Selector` — which space the state is in: attention between the encoded state and the
  learned node identifiers h_i (Eq. 4.4), trained by cross-entropy on labelled states (Eq. 4.5).
* :class:`Evaluator` — from which reachable node to solve the task: attention scores between the
  encoded state and the identifiers of V_i ∪ {i}, a sampled choice, trained to maximise return.
* :class:`ExternalAgent` — node i's option that moves the state to a neighbour S_j, a SAC on
  [s | one-hot(j)], trained with hindsight relabelling (:func:`external_reward`).
* :class:`InternalAgent` — solves the task inside S_i, a SAC whose target at boundary states
  borrows the neighbour node's value (:func:`boundary_values`); :class:`SharedInternal` one
  SAC on [s | one-hot(i)] for every node instead; :class:`ControllerAgent` puts a
  convex-optimisation controller (an inverse QP) in its place.
* :func:`option_transitions` — the transitions of Eq. 4.6.
"""

from __future__ import annotations

import copy
from collections.abc import Callable, Collection, Sequence

import numpy as np
import torch
from torch import nn
from torch.nn import functional as F

from pliant.errors import TrainingError
from pliant.learn.graph.sac import SAC, ReplayBuffer, mlp, polyak

#: External rewards [step still in S_i, reached the target node, reached another node] (D.2).
EXTERNAL_REWARDS = (-1.0, 2.0, -2.0)


class NodeAttention(nn.Module):
    """Scores s -> F(s) Hᵀ/√d between an MLP encoding F(s) ∈ R^d and the node identifiers
    H = [h_1 … h_N] (Eq. 4.4 before the softmax)."""

    def __init__(self, obs_dim: int, n_nodes: int, d: int, hidden: int) -> None:
        super().__init__()
        self.d = d
        self.encoder = mlp(obs_dim, d, hidden)
        self.identifiers = nn.Parameter(torch.randn(n_nodes, d))

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        return self.encoder(obs) @ self.identifiers.T / np.sqrt(self.d)


class Selector(nn.Module):
    """Which configuration space a state is in: α = softmax(Q Kᵀ/√d), K = F(s_t) the encoded
    state, Q the identifiers (Eq. 4.4); current space = argmax α. Trained on labelled states with
    targets α_i = 1 for the true space, 0 elsewhere, i.e. cross-entropy (Eq. 4.5)."""

    def __init__(self, obs_dim: int, n_nodes: int, *, d: int = 64, hidden: int = 256) -> None:
        super().__init__()
        self.n_nodes = n_nodes
        self.attention = NodeAttention(obs_dim, n_nodes, d, hidden)

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        """Probabilities α (batch, N)."""
        return self.attention(obs).softmax(-1)

    @torch.no_grad()
    def predict(self, obs: np.ndarray) -> np.ndarray:
        obs_t = torch.as_tensor(np.asarray(obs, dtype=np.float32))
        return self.attention(obs_t).argmax(-1).numpy()

    def accuracy(self, obs: np.ndarray, labels: np.ndarray) -> float:
        return float(np.mean(self.predict(obs) == np.asarray(labels)))

    def fit(
        self,
        obs: np.ndarray,
        labels: np.ndarray,
        *,
        epochs: int = 50,
        batch_size: int = 64,
        lr: float = 1e-4,
        validation: float = 0.2,
        balance: bool = True,
        schedule: str = "constant",
        seed: int = 0,
    ) -> dict[str, list[float]]:
        """Supervised training (Eq. 4.5). ``validation`` of the data is held out (thesis 20 %);
        ``balance`` subsamples every class to the smallest one (D.2); ``schedule`` the
        learning rate over the epochs, ``"constant"`` or ``"cosine"`` (annealed to 0, which
        sharpens the boundaries between spaces where a constant rate keeps jittering them).
        Keeps the parameters of the best validation accuracy; returns the history."""
        if schedule not in ("constant", "cosine"):
            raise TrainingError(f"schedule must be 'constant' or 'cosine', got {schedule!r}")
        rng = np.random.default_rng(seed)
        obs, labels = np.asarray(obs, dtype=np.float32), np.asarray(labels, dtype=np.int64)
        if balance:
            counts = np.bincount(labels, minlength=self.n_nodes)
            smallest = counts[counts > 0].min()
            keep = np.concatenate(
                [rng.permutation(np.flatnonzero(labels == c))[:smallest] for c in np.unique(labels)]
            )
            obs, labels = obs[keep], labels[keep]
        order = rng.permutation(len(labels))
        n_val = int(round(validation * len(order)))
        val, train = order[:n_val], order[n_val:]
        x, y = torch.as_tensor(obs[train]), torch.as_tensor(labels[train])
        optimiser = torch.optim.Adam(self.parameters(), lr=lr)
        annealing = (
            torch.optim.lr_scheduler.CosineAnnealingLR(optimiser, epochs)
            if schedule == "cosine"
            else None
        )
        history: dict[str, list[float]] = {"loss": [], "val_accuracy": []}
        best, best_state = -1.0, None
        for _ in range(epochs):
            perm = torch.as_tensor(rng.permutation(len(train)))
            for start in range(0, len(train), batch_size):
                index = perm[start : start + batch_size]
                loss = F.cross_entropy(self.attention(x[index]), y[index])
                optimiser.zero_grad()
                loss.backward()
                optimiser.step()
            if annealing is not None:
                annealing.step()
            history["loss"].append(loss.item())
            if n_val:
                accuracy = self.accuracy(obs[val], labels[val])
                history["val_accuracy"].append(accuracy)
                if accuracy > best:
                    best, best_state = accuracy, copy.deepcopy(self.state_dict())
        if best_state is not None:
            self.load_state_dict(best_state)
        return history


class Evaluator(nn.Module):
    """Which node of V_i ∪ {i} to solve the task from (Eq. 4.3).

    The scores of the reachable nodes are attention between the encoded state and the node
    identifiers (Eq. 4.4), read as Q-values of the choice: the choice is sampled from
    softmax(scores / temperature) over V_i ∪ {i} and the scores regress on the return of the
    option that follows (semi-Markov Q-learning on the transitions of Eq. 4.6). The thesis'
    authors instead feed SAC's tanh-Gaussian output to the softmax (D.2); both sample the
    choice and maximise the return.

    ``target`` is the bootstrap value of the state an option ends in: ``"max"`` (default)
    the target network's score of the online network's best choice (double Q-learning);
    ``"soft"`` τ log Σ_j exp(Q(s, j)/τ), the entropy-regularised value. The soft value is
    biased towards deciding often: it exceeds max_j Q by up to τ log |V_i ∪ {i}| at every
    decision, so a chain of short options collects that bonus once per link where one long
    option (a controller run to its end) collects it once. With CartStemContact's returns of
    about −1 an episode and τ = 0.5, that bonus (0.35–0.55 a decision) taught the greedy
    Evaluator to bounce between neighbour nodes instead of solving where it was.

    ``target_entropy`` (a fraction in (0, 1), or None) tunes the sampling temperature as SAC
    tunes its own (the authors' Evaluator is a SAC): after each update, log τ takes one
    gradient step on log τ · (H − fraction · log n), H the entropy of softmax(Q/τ) over the n
    choices available on the batch's states, so that the sampled choice keeps that fraction
    of the uniform choice's entropy whatever the scale of the Q-values. With a fixed τ the
    Q-values of CartStemContact's choices, tenths apart, left the sampling near uniform for
    the whole run (two thirds of the training decisions moved the state to another node).
    """

    def __init__(
        self,
        obs_dim: int,
        reachable: np.ndarray,
        *,
        d: int = 64,
        hidden: int = 256,
        lr: float = 3e-4,
        gamma: float = 0.99,
        tau: float = 5e-3,
        temperature: float = 0.5,
        target: str = "max",
        target_entropy: float | None = None,
    ) -> None:
        super().__init__()
        if target not in ("max", "soft"):
            raise TrainingError(f"Evaluator target must be 'max' or 'soft', got {target!r}")
        if not temperature > 0.0:
            raise TrainingError(f"Evaluator temperature must be positive, got {temperature}")
        if target_entropy is not None and not 0.0 < target_entropy < 1.0:
            raise TrainingError(
                f"Evaluator target entropy is a fraction in (0, 1), got {target_entropy}"
            )
        self.target_kind = target
        # (nodes, choices): the nodes V_i ∪ {i}, then any expert options available in node i.
        self.reachable = torch.as_tensor(np.asarray(reachable, dtype=bool))
        self.gamma, self.tau = gamma, tau
        self.attention = NodeAttention(obs_dim, self.reachable.shape[1], d, hidden)
        self.target = copy.deepcopy(self.attention).requires_grad_(False)
        self.optimiser = torch.optim.Adam(self.attention.parameters(), lr=lr)
        self.target_entropy = target_entropy
        self._temperature = float(temperature)
        if target_entropy is not None:
            self.log_temperature = nn.Parameter(torch.tensor(float(np.log(temperature))))
            self.temperature_optimiser = torch.optim.Adam([self.log_temperature], lr=lr)

    @property
    def temperature(self) -> float:
        """The sampling temperature τ (tuned when a target entropy is set)."""
        if self.target_entropy is None:
            return self._temperature
        return float(self.log_temperature.exp())

    @temperature.setter
    def temperature(self, value: float) -> None:
        if not value > 0.0:
            raise TrainingError(f"Evaluator temperature must be positive, got {value}")
        if self.target_entropy is None:
            self._temperature = float(value)
        else:  # the tuning goes on from there
            with torch.no_grad():
                self.log_temperature.fill_(float(np.log(value)))

    def scores(self, obs: torch.Tensor, node: torch.Tensor, target: bool = False):
        """Q(s, j) for every choice j (the nodes, then the expert options), −inf where j is
        not available in ``node``."""
        q = (self.target if target else self.attention)(obs)
        return q.masked_fill(~self.reachable[node.long()], -torch.inf)

    @torch.no_grad()
    def choose(
        self,
        obs: np.ndarray,
        node: int,
        rng: np.random.Generator,
        greedy: bool = False,
        exclude: Collection[int] = (),
    ) -> int:
        """The greedy choice (argmax Q) or one sampled from softmax(Q/τ), among the choices
        available in ``node`` less ``exclude``; all available ones when ``exclude`` would
        leave none."""
        q = self.scores(torch.as_tensor(np.asarray(obs, np.float32))[None], torch.tensor([node]))[0]
        if exclude:
            kept = q.clone()
            kept[list(exclude)] = -torch.inf
            if torch.isfinite(kept).any():
                q = kept
        if greedy:
            return int(q.argmax())
        p = (q / self.temperature).softmax(-1).numpy().astype(float)
        return int(rng.choice(len(p), p=p / p.sum()))

    @torch.no_grad()
    def value(self, obs: torch.Tensor, node: torch.Tensor) -> torch.Tensor:
        """The bootstrap value V(s) over the choices available in ``node`` (see ``target``):
        the target network's Q of the online argmax, or the soft value."""
        q = self.scores(obs, node, target=True)
        if self.target_kind == "soft":
            return self.temperature * torch.logsumexp(q / self.temperature, dim=-1)
        best = self.scores(obs, node).argmax(-1, keepdim=True)
        return q.gather(1, best).squeeze(1)

    def update(self, batch: dict[str, torch.Tensor]) -> float:
        q = self.scores(batch["obs"], batch["node"]).gather(1, batch["choice"].long()[:, None])
        next_value = self.value(batch["next_obs"], batch["next_node"])
        discount = self.gamma ** batch["duration"]
        y = batch["reward"] + discount * (1.0 - batch["done"]) * next_value
        loss = F.mse_loss(q.squeeze(1), y)
        self.optimiser.zero_grad()
        loss.backward()
        self.optimiser.step()
        polyak(self.attention, self.target, self.tau)
        if self.target_entropy is not None:
            self._tune_temperature(batch["obs"], batch["node"])
        return loss.item()

    def _tune_temperature(self, obs: torch.Tensor, node: torch.Tensor) -> None:
        """One step of log τ towards the target entropy on these states (class docstring)."""
        with torch.no_grad():
            q = self.scores(obs, node)
            p = (q / self.temperature).softmax(-1)
            entropy = -(p * torch.log(p.clamp_min(1e-12))).sum(-1)
            n = self.reachable[node.long()].sum(-1).float()
            gap = entropy - self.target_entropy * torch.log(n)
        loss = (self.log_temperature * gap).mean()
        self.temperature_optimiser.zero_grad()
        loss.backward()
        self.temperature_optimiser.step()


def with_node(obs: torch.Tensor, node: torch.Tensor, n_nodes: int) -> torch.Tensor:
    """[s | one-hot(node)]: a batch of observations conditioned on a node (the external
    agents' target node, the shared internal agent's own node)."""
    return torch.cat([obs, F.one_hot(node.long(), n_nodes).float()], dim=-1)


def act_on_node(sac: SAC, obs: np.ndarray, node: int, n_nodes: int, deterministic: bool):
    """The action of a SAC on [s | one-hot(node)] for one observation."""
    x = with_node(torch.as_tensor(np.asarray(obs, np.float32))[None], torch.tensor([node]), n_nodes)
    return sac.act(x[0].numpy(), deterministic)


def option_transitions(
    observations: Sequence[np.ndarray], rewards: Sequence[float], done: bool
) -> list[dict]:
    """The transitions of one option (Eq. 4.6): for k ∈ [0, T−1],
    (s_{t+k}, a_t, s_{t+T}, Σ_{t'=t+k}^{t+T−1} r_{t'}, δ), with its duration T − k for the
    discount γ^{T−k} of the bootstrap. ``observations`` = s_t … s_{t+T} (T + 1 of them),
    ``rewards`` = r_t … r_{t+T−1} (r_{t'} received on the step s_{t'} -> s_{t'+1}; the thesis'
    upper bound t + T counts the same T − k rewards from 1), ``done`` = δ, the episode ended at
    s_{t+T}. The option's action a_t is the caller's (the chosen node)."""
    T = len(rewards)
    if len(observations) != T + 1:
        raise TrainingError(f"{len(observations)} observations for {T} rewards (need T + 1)")
    tails = np.cumsum(np.asarray(rewards, dtype=float)[::-1])[::-1]
    return [
        {
            "obs": observations[k],
            "next_obs": observations[T],
            "reward": float(tails[k]),
            "done": float(done),
            "duration": T - k,
        }
        for k in range(T)
    ]


def external_reward(
    node: int,
    reached: torch.Tensor,
    goal: torch.Tensor,
    rewards: Sequence[float] = EXTERNAL_REWARDS,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Hindsight rewards of node i's external agent for goal nodes ``goal`` (D.1, D.2): a step
    that stays in S_i costs rewards[0]; one reaching S_goal earns rewards[1]; one reaching any
    other space, rewards[2]. Leaving S_i ends the option (done = 1). A trajectory reaching S_k is
    so rewarded for goal k and penalised for every other goal."""
    stay, hit, miss = rewards
    left = reached != node
    reward = torch.where(left, torch.where(reached == goal, hit, miss), stay).float()
    return reward, left.float()


class ExternalAgent:
    """Node i's option to a neighbour space: a SAC on [s | one-hot(target node)].

    Trained off-policy on every transition that starts in S_i, whoever acted, each relabelled
    for a target drawn among V_i (:func:`external_reward`)."""

    def __init__(
        self,
        node: int,
        neighbours: Sequence[int],
        n_nodes: int,
        obs_dim: int,
        act_dim: int,
        *,
        rewards: Sequence[float] = EXTERNAL_REWARDS,
        buffer_size: int = 100_000,
        **sac_kwargs,
    ) -> None:
        self.node, self.neighbours, self.n_nodes = node, list(neighbours), n_nodes
        self.rewards = tuple(rewards)
        self.sac = SAC(obs_dim + n_nodes, act_dim, **sac_kwargs)
        self.buffer = ReplayBuffer(
            buffer_size, obs=(obs_dim,), action=(act_dim,), next_obs=(obs_dim,), next_node=(),
            terminal=(),
        )  # fmt: skip

    def goal_input(self, obs: torch.Tensor, goal: torch.Tensor) -> torch.Tensor:
        return with_node(obs, goal, self.n_nodes)

    def act(self, obs: np.ndarray, goal: int, deterministic: bool = False) -> np.ndarray:
        return act_on_node(self.sac, obs, goal, self.n_nodes, deterministic)

    def update(self, batch_size: int, rng: np.random.Generator) -> dict[str, float]:
        b = self.buffer.sample(batch_size, rng)
        goal = torch.as_tensor(rng.choice(self.neighbours, size=batch_size))
        reward, left = external_reward(self.node, b["next_node"], goal, self.rewards)
        done = torch.maximum(left, b["terminal"])
        return self.sac.update(
            self.goal_input(b["obs"], goal), b["action"], reward,
            self.goal_input(b["next_obs"], goal), done,
        )  # fmt: skip


class InternalAgent:
    """Node i's task solver with primitive actions: a SAC on the task reward, trained on every
    transition that starts in S_i; at boundary states the bootstrap is the value of the node the
    next state is in (:func:`boundary_values`)."""

    learned = True

    def __init__(
        self, node: int, obs_dim: int, act_dim: int, *, buffer_size: int = 100_000, **sac_kwargs
    ) -> None:
        self.node = node
        self.sac = SAC(obs_dim, act_dim, **sac_kwargs)
        self.buffer = ReplayBuffer(
            buffer_size, obs=(obs_dim,), action=(act_dim,), reward=(), next_obs=(obs_dim,),
            next_node=(), terminal=(),
        )  # fmt: skip

    def act(self, obs: np.ndarray, deterministic: bool = False) -> np.ndarray:
        return self.sac.act(obs, deterministic)

    def value(self, obs: torch.Tensor) -> torch.Tensor:
        return self.sac.soft_value(obs)

    def store(self, item: dict) -> None:
        """Keep a transition that starts in S_i (keys of the buffer's fields)."""
        self.buffer.add(**item)


class SharedInternal:
    """One SAC on [s | one-hot(i)] for the internal agents of every learned node (a departure
    from the thesis' one SAC per node, ``GraphConfig.internal = "shared"``).

    Each node keeps its own policy and critic, π(a | s, h_i) and Q(s, h_i, a), but they share
    their weights and one replay buffer of every primitive transition, each labelled with the
    node it starts in: a node visited rarely learns from what the others learnt about the same
    dynamics and reward, where per-node agents each start from scratch on their share of the
    data. The boundary borrowing stays exact: the bootstrap of a transition that ends in S_k is
    V(s', h_k), node k's own value (the starting node's where node k has no learned agent)."""

    def __init__(
        self, n_nodes: int, obs_dim: int, act_dim: int, *, buffer_size: int = 100_000,
        **sac_kwargs,
    ) -> None:  # fmt: skip
        self.n_nodes = n_nodes
        self.sac = SAC(obs_dim + n_nodes, act_dim, **sac_kwargs)
        self.buffer = ReplayBuffer(
            buffer_size, obs=(obs_dim,), node=(), action=(act_dim,), reward=(),
            next_obs=(obs_dim,), next_node=(), terminal=(),
        )  # fmt: skip

    def node_input(self, obs: torch.Tensor, node: torch.Tensor) -> torch.Tensor:
        return with_node(obs, node, self.n_nodes)

    def update(
        self,
        agents: Sequence[InternalAgent | ControllerAgent | SharedInternalAgent],
        batch_size: int,
        rng: np.random.Generator,
    ) -> dict[str, float]:
        """One SAC step on a batch of every node's transitions, each bootstrapped from the
        value of the node its next state is in (its own node's where that one has no learned
        agent: a :class:`ControllerAgent`)."""
        b = self.buffer.sample(batch_size, rng)
        learned = torch.tensor([a.learned for a in agents])
        owner = torch.where(learned[b["next_node"].long()], b["next_node"], b["node"])
        next_input = self.node_input(b["next_obs"], owner)
        return self.sac.update(
            self.node_input(b["obs"], b["node"]), b["action"], b["reward"], next_input,
            b["terminal"], self.sac.soft_value(next_input),
        )  # fmt: skip


class SharedInternalAgent:
    """Node i's internal agent as a view of a :class:`SharedInternal` network: π(a | s, h_i)."""

    learned = True

    def __init__(self, node: int, shared: SharedInternal) -> None:
        self.node, self.shared = node, shared

    def act(self, obs: np.ndarray, deterministic: bool = False) -> np.ndarray:
        shared = self.shared
        return act_on_node(shared.sac, obs, self.node, shared.n_nodes, deterministic)

    def value(self, obs: torch.Tensor) -> torch.Tensor:
        node = torch.full((len(obs),), self.node)
        return self.shared.sac.soft_value(self.shared.node_input(obs, node))

    def store(self, item: dict) -> None:
        self.shared.buffer.add(node=self.node, **item)


class ControllerAgent:
    """An internal agent replaced by a controller, e.g. convex optimisation (the inverse QP/QPCC
    of :class:`pliant.constraints.control.InverseControl`): ``controller(obs)`` -> action in
    [-1, 1]^m. The hierarchy runs it as an option until the node changes (or the episode ends,
    or ``option_limit`` steps pass; with ``GraphConfig.controller_crosses``, on across node
    changes). It has no critic: boundary targets of its neighbours fall
    back on their own."""

    learned = False

    def __init__(self, node: int, controller: Callable[[np.ndarray], np.ndarray]) -> None:
        self.node, self.controller = node, controller

    def act(self, obs: np.ndarray, deterministic: bool = True) -> np.ndarray:
        return np.asarray(self.controller(obs), dtype=np.float32)


class ExpertOption:
    """An expert trajectory used as an external option (thesis §4.2.2: the RodManipulator's
    re-contact sequences, which move the fingers away and bring them back on the rod from the
    other side), in the agents' action scale, [-1, 1]^m, which the Evaluator may choose in any
    node of ``start_nodes``. ``actions`` is the open-loop sequence, a (T, m) array (the
    authors' experts), or a callable ``(obs, k) -> action`` for step k of ``steps`` (an expert
    that places the robot from where it is, e.g. an inverse controller with its own goals).
    It runs for its T steps (or to the episode's end) through whatever nodes it crosses, its
    primitive transitions feeding the agents of the nodes they start in, and its return is
    charged ``penalty`` once (the thesis penalises using them). The Evaluator scores it with
    an identifier of its own, beside the nodes'."""

    def __init__(
        self,
        name: str,
        actions,
        start_nodes: Sequence[int],
        penalty: float = 0.0,
        *,
        steps: int | None = None,
        action_dim: int | None = None,
    ) -> None:
        if callable(actions):
            if steps is None or action_dim is None or steps < 1 or action_dim < 1:
                raise TrainingError(f"expert {name!r}: a policy needs steps >= 1 and action_dim")
            self.policy, self.steps, self.action_dim = actions, int(steps), int(action_dim)
        else:
            table = np.asarray(actions, dtype=np.float32)
            if table.ndim != 2 or table.shape[0] == 0:
                raise TrainingError(f"expert {name!r}: actions must be a non-empty (T, m) array")
            if not np.all(np.isfinite(table)) or np.abs(table).max() > 1.0:
                raise TrainingError(f"expert {name!r}: actions must be finite and within [-1, 1]")
            self.policy = lambda obs, k: table[k]
            self.steps, self.action_dim = table.shape
        if not start_nodes:
            raise TrainingError(f"expert {name!r}: give the nodes it may start from")
        if not np.isfinite(penalty):
            raise TrainingError(f"expert {name!r}: penalty must be finite, got {penalty!r}")
        self.name = name
        self.start_nodes = tuple(int(i) for i in start_nodes)
        self.penalty = float(penalty)

    def __len__(self) -> int:
        return self.steps

    def act(self, obs: np.ndarray, k: int) -> np.ndarray:
        """The action of step k (0-based) from observation ``obs``."""
        action = np.asarray(self.policy(obs, k), dtype=np.float32).reshape(-1)
        if action.shape != (self.action_dim,) or not np.all(np.isfinite(action)):
            raise TrainingError(
                f"expert {self.name!r}: step {k} gave {action!r}, not {self.action_dim} finite"
                " values"
            )
        return np.clip(action, -1.0, 1.0)


def boundary_values(
    agents: Sequence[InternalAgent | ControllerAgent],
    node: int,
    next_obs: torch.Tensor,
    next_node: torch.Tensor,
) -> torch.Tensor:
    """Bootstrap values V(s') for node ``node``'s internal agent (thesis L821): inside S_node
    its own critic; where s' lies in a neighbour space S_k (a boundary transition) the critic of
    node k's internal agent, when it has one."""
    values = torch.empty(len(next_obs))
    for k in torch.unique(next_node.long()).tolist():
        owner = agents[k] if agents[k].learned else agents[node]
        rows = next_node.long() == k
        values[rows] = owner.value(next_obs[rows])
    return values


def update_internal(
    agents: Sequence[InternalAgent | ControllerAgent],
    node: int,
    batch_size: int,
    rng: np.random.Generator,
) -> dict[str, float]:
    """One SAC step of node ``node``'s internal agent with boundary-borrowed targets."""
    b = agents[node].buffer.sample(batch_size, rng)
    next_value = boundary_values(agents, node, b["next_obs"], b["next_node"])
    return agents[node].sac.update(
        b["obs"], b["action"], b["reward"], b["next_obs"], b["terminal"], next_value
    )
