"""The hierarchy that runs and trains the graph's agents on a Gymnasium environment
(thesis §4.2.1, Fig. 4.7).

At each decision the current node i comes from the graph's partition function (collision
detection, geometry) or the Selector; the Evaluator picks j ∈ V_i ∪ {i}; j ≠ i runs node i's
external agent towards S_j until the state leaves S_i (or ``option_limit`` steps, or the
episode ends); j = i runs node i's internal agent for one step (T = 1), or, when it is a
:class:`ControllerAgent`, until the node changes (with ``controller_crosses``, on across
node changes, until the episode ends or ``option_limit`` steps pass); a choice j ≥ N
(N nodes) runs expert option j − N (:class:`ExpertOption`) to its end; with ``avoid_cycles``
a choice that took the state out of node i is not chosen again on a return to i. Every primitive
transition that starts in S_i feeds node i's internal and external buffers; every option feeds
the Evaluator with the transitions of Eq. 4.6, penalised (``penalty``) when an internal agent
changed the space.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import gymnasium as gym
import numpy as np
import torch

from pliant.errors import TrainingError
from pliant.files import atomic_path, read_checked
from pliant.learn.graph.agents import (
    EXTERNAL_REWARDS,
    ControllerAgent,
    Evaluator,
    ExpertOption,
    ExternalAgent,
    InternalAgent,
    Selector,
    SharedInternal,
    SharedInternalAgent,
    option_transitions,
    update_internal,
)
from pliant.learn.graph.graph import ConfigurationGraph
from pliant.learn.graph.sac import ReplayBuffer


@dataclass
class GraphConfig:
    """Hyper-parameters (defaults: D.2 where the authors' code gives them)."""

    hidden: int = 256
    d: int = 64
    lr: float = 3e-4
    gamma: float = 0.99
    tau: float = 5e-3
    batch_size: int = 256
    buffer_size: int = 100_000
    learning_starts: int = 500
    updates_per_step: float = 1.0
    #: the authors' schedule (D.2): this many gradient steps of every agent (each node's
    #: internal and external ones, the Evaluator) after each training episode, none during it;
    #: None: ``updates_per_step`` during the episode. Plain SAC follows the same schedule.
    updates_per_episode: int | None = None
    #: which agents a per-step update trains: "node" (those of the node the transition
    #: started in, and the Evaluator: each agent learns as often as its node is visited),
    #: "internal" (every node's internal agent, the node's external one and the Evaluator:
    #: each internal agent takes as many gradient steps as plain SAC's one network, the
    #: external agents as often as their node is visited) or "all" (every agent that holds a
    #: batch, as the authors' after-episode schedule does).
    update_scope: str = "node"
    option_limit: int = 30
    penalty: float = -1.0
    external_rewards: tuple[float, float, float] = EXTERNAL_REWARDS
    evaluator_temperature: float = 0.5
    evaluator_tau: float = 5e-3
    #: the Evaluator's bootstrap: "max" (double Q) or "soft" (biased towards short options;
    #: the runs before 2026-11-26 used it, see :class:`Evaluator`).
    evaluator_target: str = "max"
    #: tune the Evaluator's temperature to keep this fraction of the uniform choice's entropy
    #: (SAC's rule; None: the fixed ``evaluator_temperature``, its starting value otherwise).
    evaluator_entropy: float | None = None
    #: the internal agents: "per_node" (one SAC each, the thesis') or "shared" (one SAC on
    #: [s | one-hot(i)] for all, trained on every transition: :class:`SharedInternal`).
    internal: str = "per_node"
    #: a controller internal agent (:class:`ControllerAgent`) keeps acting when its actions
    #: take the state into another node, until the episode ends or ``option_limit`` steps
    #: pass (a departure: the issue's controller hands back when the node changes). For an
    #: Evaluator trained with learned agents that solve from inside a node whose controller's
    #: solution lies outside it (docs/graph.md, the swap goal by goal).
    controller_crosses: bool = False
    #: within an episode, a choice that took the state out of node i is not chosen again when
    #: the state is back in node i (unless every choice there has done so): the Evaluator
    #: cannot send the state round the same loop twice (a departure; an Evaluator trained with
    #: other internal agents than it acts with bounces between two nodes otherwise:
    #: docs/graph.md, the swap goal by goal).
    avoid_cycles: bool = False


def final_numbers(infos: list[dict]) -> dict[str, float]:
    """``final_<key>``: the mean over episodes of each real number in their last ``info``
    (booleans, e.g. ``is_success``, left out: success is reported on its own)."""
    keys = set.intersection(*(set(i) for i in infos)) if infos else set()
    out = {}
    for key in sorted(keys):
        values = [i[key] for i in infos]
        if all(isinstance(v, numbers.Real) and not isinstance(v, bool) for v in values):
            out[f"final_{key}"] = float(np.mean(values))
    return out


def episode_means(runs: list[dict]) -> dict[str, float]:
    """Mean return and success of greedy episodes (``run_episode``'s dicts), and
    :func:`final_numbers` of their last ``info``."""
    return {
        "return": float(np.mean([r["return"] for r in runs])),
        "success": float(np.mean([r["success"] for r in runs])),
        **final_numbers([r["info"] for r in runs]),
    }


def train_and_evaluate(
    agent, env, total_steps, eval_env, eval_every, eval_episodes, callback
) -> list[dict]:
    """`agent`'s training episodes until ``total_steps`` environment steps, evaluated every
    ``eval_every`` steps (``agent.learn`` of :class:`GraphAgent` and of the flat baseline).
    Returns the evaluations [{steps, return, success}]."""
    history = []
    next_eval = agent.next_eval if agent.next_eval is not None else agent.steps + eval_every
    while agent.steps < total_steps:
        agent.run_episode(env, train=True, seed=int(agent.rng.integers(2**31)))
        if eval_every and agent.steps >= next_eval:
            next_eval += eval_every
            agent.next_eval = next_eval  # a checkpoint the callback saves resumes on time
            result = {"steps": agent.steps, **agent.evaluate(eval_env or env, eval_episodes)}
            history.append(result)
            if callback is not None:
                callback(result)
    return history


def check_schedule(config: GraphConfig) -> None:
    """TrainingError unless the update schedule is one: a positive rate per step, or a
    positive whole number of updates per episode."""
    if not (math.isfinite(config.updates_per_step) and config.updates_per_step > 0):
        raise TrainingError(f"updates_per_step must be > 0, got {config.updates_per_step}")
    per_episode = config.updates_per_episode
    if per_episode is not None and not (isinstance(per_episode, int) and per_episode >= 1):
        raise TrainingError(f"updates_per_episode must be a whole number >= 1, got {per_episode}")
    if config.update_scope not in ("node", "internal", "all"):
        raise TrainingError(
            f"update_scope must be 'node', 'internal' or 'all', got {config.update_scope!r}"
        )


class GraphAgent:
    """Selector (or partition), Evaluator, and one external and one internal agent per node.

    Args:
        graph: the configuration-space graph.
        observation_space, action_space: the environment's (a Box action space).
        config: hyper-parameters.
        controllers: ``{node: controller}`` replaces those nodes' internal agents by
            :class:`ControllerAgent` (convex optimisation).
        selector: a trained :class:`Selector`, used where the graph has no partition function.
        experts: :class:`ExpertOption` s, more choices of the Evaluator in their start nodes
            (choice ``n_nodes + k`` is expert k).
        seed: seeds torch and the agent's random generator.
    """

    def __init__(
        self,
        graph: ConfigurationGraph,
        observation_space: gym.spaces.Box,
        action_space: gym.spaces.Box,
        config: GraphConfig | None = None,
        *,
        controllers: dict[int, Callable[[np.ndarray], np.ndarray]] | None = None,
        selector: Selector | None = None,
        experts: Sequence[ExpertOption] = (),
        seed: int = 0,
    ) -> None:
        self.config = c = config or GraphConfig()
        if c.internal not in ("per_node", "shared"):
            raise TrainingError(f"internal must be 'per_node' or 'shared', got {c.internal!r}")
        check_schedule(c)
        for flag in ("controller_crosses", "avoid_cycles"):
            if not isinstance(getattr(c, flag), bool):
                raise TrainingError(f"{flag} is True or False, got {getattr(c, flag)!r}")
        if graph.partition is None and selector is None:
            raise TrainingError("the graph has no partition function: give a trained Selector")
        self.experts = list(experts)
        for expert in self.experts:
            if expert.action_dim != action_space.shape[0]:
                raise TrainingError(
                    f"expert {expert.name!r} has {expert.action_dim} action values, the"
                    f" environment {action_space.shape[0]}"
                )
            if not all(0 <= i < graph.n_nodes for i in expert.start_nodes):
                raise TrainingError(f"expert {expert.name!r}: start nodes outside the graph")
        torch.manual_seed(seed)
        self.rng = np.random.default_rng(seed)
        self.graph, self.selector = graph, selector
        self.low, self.high = action_space.low, action_space.high
        n, obs_dim, act_dim = graph.n_nodes, observation_space.shape[0], action_space.shape[0]
        sac = {"hidden": c.hidden, "lr": c.lr, "gamma": c.gamma, "tau": c.tau}
        controllers = controllers or {}
        self.shared_internal = (
            SharedInternal(n, obs_dim, act_dim, buffer_size=c.buffer_size, **sac)
            if c.internal == "shared" and set(range(n)) - set(controllers)
            else None
        )
        self.internal = [
            ControllerAgent(i, controllers[i])
            if i in controllers
            else SharedInternalAgent(i, self.shared_internal)
            if self.shared_internal is not None
            else InternalAgent(i, obs_dim, act_dim, buffer_size=c.buffer_size, **sac)
            for i in range(n)
        ]
        self.external = [
            ExternalAgent(
                i, graph.neighbours(i), n, obs_dim, act_dim,
                rewards=c.external_rewards, buffer_size=c.buffer_size, **sac,
            ) if graph.neighbours(i) else None
            for i in range(n)
        ]  # fmt: skip
        choices = np.zeros((n, n + len(self.experts)), dtype=bool)
        choices[:, :n] = graph.reachable_mask()
        for k, expert in enumerate(self.experts):
            choices[list(expert.start_nodes), n + k] = True
        self.evaluator = Evaluator(
            obs_dim, choices, d=c.d, hidden=c.hidden, lr=c.lr, gamma=c.gamma,
            tau=c.evaluator_tau, temperature=c.evaluator_temperature, target=c.evaluator_target,
            target_entropy=c.evaluator_entropy,
        )  # fmt: skip
        self.evaluator_buffer = ReplayBuffer(
            c.buffer_size, obs=(obs_dim,), node=(), choice=(), reward=(), next_obs=(obs_dim,),
            next_node=(), done=(), duration=(),
        )  # fmt: skip
        self.steps = 0
        self._update_debt = 0.0
        #: the step count of the next evaluation of :meth:`learn` (kept by a checkpoint)
        self.next_eval: int | None = None

    def swap_internal(self, controllers: dict[int, Callable[[np.ndarray], np.ndarray]]) -> None:
        """Replace the internal agents of the nodes in ``controllers`` by those controllers
        (:class:`ControllerAgent`), keeping the Evaluator and the external agents as trained:
        the thesis' measurement of trained internal agents swapped for convex optimisation
        (L863). The learned agents are dropped from this agent (reload a checkpoint to get
        them back)."""
        for node, controller in controllers.items():
            if not 0 <= node < self.graph.n_nodes:
                raise TrainingError(f"no node {node} in a graph of {self.graph.n_nodes}")
            self.internal[node] = ControllerAgent(node, controller)

    # ---- acting -------------------------------------------------------------------------------
    def node_of(self, obs: np.ndarray) -> int:
        if self.graph.partition is not None:
            return self.graph.node_of(obs)
        return int(self.selector.predict(np.asarray(obs)[None])[0])

    def _scale(self, action: np.ndarray) -> np.ndarray:
        return self.low + 0.5 * (np.clip(action, -1.0, 1.0) + 1.0) * (self.high - self.low)

    def _primitive(self, obs, node: int, choice: int, explore: bool) -> np.ndarray:
        if choice == node and not self.internal[node].learned:
            return self.internal[node].act(obs)
        if explore and self.steps < self.config.learning_starts:
            return self.rng.uniform(-1.0, 1.0, size=self.low.shape).astype(np.float32)
        if choice == node:
            return self.internal[node].act(obs, deterministic=not explore)
        return self.external[node].act(obs, choice, deterministic=not explore)

    def run_episode(self, env: gym.Env, *, train: bool, seed: int | None = None) -> dict:
        """One episode; with ``train`` it explores, stores and learns. Returns its return,
        length, success, the node sequence, the Evaluator's choices (node k: that node's
        agent; ``n_nodes + k``: expert k) and the last ``info``."""
        obs, _ = env.reset(seed=seed)
        node, n = self.node_of(obs), self.graph.n_nodes
        total, length, nodes, done, success = 0.0, 0, [node], False, False
        choices = []
        left: dict[int, set[int]] = {}  # node -> the choices that took the state out of it
        while not done:
            exclude = left.get(node, ()) if self.config.avoid_cycles else ()
            choice = self.evaluator.choose(obs, node, self.rng, greedy=not train, exclude=exclude)
            choices.append(choice)
            expert = self.experts[choice - n] if choice >= n else None
            runs_option = choice != node or not self.internal[node].learned
            crosses = (
                self.config.controller_crosses
                and choice == node
                and not self.internal[node].learned
            )
            observations, rewards, current = [obs], [], node
            while True:
                if expert is not None:
                    action = expert.act(obs, len(rewards))
                else:
                    action = self._primitive(obs, node, choice, explore=train)
                next_obs, reward, terminated, truncated, info = env.step(self._scale(action))
                next_node = self.node_of(next_obs)
                total, length = total + float(reward), length + 1
                done = terminated or truncated
                success = success or bool(info.get("is_success", terminated))
                if train:
                    self._store(obs, action, reward, next_obs, current, next_node, terminated)
                observations.append(next_obs)
                rewards.append(float(reward))
                obs = next_obs
                if expert is not None:  # runs to its end, through the nodes it crosses
                    if next_node != current:
                        nodes.append(next_node)
                    current = next_node
                    if done or len(rewards) >= len(expert):
                        break
                    continue
                if crosses and not done and len(rewards) < self.config.option_limit:
                    if next_node != current:  # on through the nodes it crosses
                        nodes.append(next_node)
                    current = next_node
                    continue
                if (
                    done
                    or next_node != node
                    or not runs_option
                    or len(rewards) >= self.config.option_limit
                ):
                    break
            if train:
                if choice == node and next_node != node:
                    rewards[-1] += self.config.penalty
                if expert is not None:
                    rewards[-1] += expert.penalty
                for t in option_transitions(observations, rewards, terminated):
                    self.evaluator_buffer.add(node=node, choice=choice, next_node=next_node, **t)
            if expert is None and next_node != current:
                nodes.append(next_node)
            if next_node != node:
                left.setdefault(node, set()).add(choice)
            node = next_node
        if train and self.config.updates_per_episode and self.steps >= self.config.learning_starts:
            for _ in range(self.config.updates_per_episode):
                self.update_all()
        return {
            "return": total, "length": length, "success": success, "nodes": nodes, "info": info,
            "choices": choices,
        }  # fmt: skip

    def _store(self, obs, action, reward, next_obs, node, next_node, terminated) -> None:
        item = {"obs": obs, "action": action, "reward": reward, "next_obs": next_obs}
        item |= {"next_node": next_node, "terminal": float(terminated)}
        if self.internal[node].learned:
            self.internal[node].store(item)
        if self.external[node] is not None:
            self.external[node].buffer.add(**item)
        self.steps += 1
        if self.steps >= self.config.learning_starts and not self.config.updates_per_episode:
            self._update_debt += self.config.updates_per_step
            while self._update_debt >= 1.0:
                self._update_debt -= 1.0
                if self.config.update_scope == "all":
                    self.update_all()
                else:
                    self.update(node, every_internal=self.config.update_scope == "internal")

    # ---- learning -----------------------------------------------------------------------------
    def update(self, node: int, every_internal: bool = False) -> None:
        """One gradient step of node ``node``'s internal and external agents (those of the node
        the last transition started in: each agent learns as often as its node is visited; a
        shared internal agent learns at every step; ``every_internal``: every node's internal
        agent) and of the Evaluator, each once its buffer holds a batch."""
        if self.shared_internal is not None:
            self._update_shared()
        for i in range(self.graph.n_nodes) if every_internal else (node,):
            self._update_internal(i)
        self._update_external(node)
        self._update_evaluator()

    def update_all(self) -> None:
        """One gradient step of every agent that holds a batch: each node's internal and
        external agents (or the shared internal one), and the Evaluator (the authors'
        after-episode schedule, :attr:`GraphConfig.updates_per_episode`)."""
        if self.shared_internal is not None:
            self._update_shared()
        for node in range(self.graph.n_nodes):
            self._update_internal(node)
            self._update_external(node)
        self._update_evaluator()

    def _update_shared(self) -> None:
        if len(self.shared_internal.buffer) >= self.config.batch_size:
            self.shared_internal.update(self.internal, self.config.batch_size, self.rng)

    def _update_internal(self, node: int) -> None:
        n = self.config.batch_size
        agent = self.internal[node]
        if self.shared_internal is None and agent.learned and len(agent.buffer) >= n:
            update_internal(self.internal, node, n, self.rng)

    def _update_external(self, node: int) -> None:
        n = self.config.batch_size
        external = self.external[node]
        if external is not None and len(external.buffer) >= n:
            external.update(n, self.rng)

    def _update_evaluator(self) -> None:
        n = self.config.batch_size
        if len(self.evaluator_buffer) >= n:
            self.evaluator.update(self.evaluator_buffer.sample(n, self.rng))

    def learn(
        self,
        env: gym.Env,
        total_steps: int,
        *,
        eval_env: gym.Env | None = None,
        eval_every: int = 0,
        eval_episodes: int = 5,
        callback: Callable[[dict], None] | None = None,
    ) -> list[dict]:
        """Train until ``total_steps`` environment steps; evaluate every ``eval_every`` steps.
        Returns the evaluations [{steps, return, success}]."""
        return train_and_evaluate(
            self, env, total_steps, eval_env, eval_every, eval_episodes, callback
        )

    def evaluate(self, env: gym.Env, episodes: int = 5, seed: int = 10_000) -> dict:
        """Mean return and success over ``episodes`` greedy episodes, and the mean of each
        number the environment's last ``info`` of an episode holds (``final_<key>``, e.g.
        RodManipulator's ``final_angle``)."""
        runs = [self.run_episode(env, train=False, seed=seed + k) for k in range(episodes)]
        return episode_means(runs)

    # ---- checkpoints --------------------------------------------------------------------------
    def state_dict(self) -> dict:
        return {
            "steps": self.steps,
            "update_debt": self._update_debt,
            "next_eval": self.next_eval,
            "rng": self.rng.bit_generator.state,
            "torch_rng": torch.get_rng_state(),
            "internal": [
                {"sac": a.sac.checkpoint(), "buffer": a.buffer.state_dict()}
                if isinstance(a, InternalAgent)
                else None
                for a in self.internal
            ],
            "shared_internal": None
            if self.shared_internal is None
            else {
                "sac": self.shared_internal.sac.checkpoint(),
                "buffer": self.shared_internal.buffer.state_dict(),
            },
            "external": [
                {"sac": a.sac.checkpoint(), "buffer": a.buffer.state_dict()} if a else None
                for a in self.external
            ],
            "evaluator": self.evaluator.state_dict(),
            "evaluator_opt": self.evaluator.optimiser.state_dict(),
            "evaluator_temperature_opt": self.evaluator.temperature_optimiser.state_dict()
            if self.evaluator.target_entropy is not None
            else None,
            "evaluator_buffer": self.evaluator_buffer.state_dict(),
        }

    def load_state_dict(self, state: dict) -> None:
        self.steps, self._update_debt = state["steps"], state["update_debt"]
        self.next_eval = state.get("next_eval")  # older checkpoints: from their step
        self.rng.bit_generator.state = state["rng"]
        torch.set_rng_state(state["torch_rng"])
        for agent, saved in [
            *zip(self.internal, state["internal"], strict=True),
            *zip(self.external, state["external"], strict=True),
        ]:
            if saved is not None:
                agent.sac.restore(saved["sac"])
                agent.buffer.load_state_dict(saved["buffer"])
        shared = state.get("shared_internal")
        if (shared is None) != (self.shared_internal is None):
            raise TrainingError(
                "the checkpoint's internal agents are not this agent's (GraphConfig.internal"
                f" is {self.config.internal!r})"
            )
        if shared is not None:
            self.shared_internal.sac.restore(shared["sac"])
            self.shared_internal.buffer.load_state_dict(shared["buffer"])
        self.evaluator.load_state_dict(state["evaluator"])
        self.evaluator.optimiser.load_state_dict(state["evaluator_opt"])
        if self.evaluator.target_entropy is not None:
            self.evaluator.temperature_optimiser.load_state_dict(state["evaluator_temperature_opt"])
        self.evaluator_buffer.load_state_dict(state["evaluator_buffer"])

    def save(self, path: str | Path) -> None:
        with atomic_path(path) as tmp:
            torch.save(self.state_dict(), tmp)

    def load(self, path: str | Path) -> None:
        state = read_checked(
            path, lambda p: torch.load(p, weights_only=False), "a graph agent checkpoint"
        )
        self.load_state_dict(state)
