"""Behaviour cloning: supervised pre-training of an SB3 policy on an expert's (observation,
action) pairs (thesis §3.2.1: the Gripper's hand-designed 4-phase strategy, 3000 epochs,
before PPO).

A short loop rather than the ``imitation`` library: ``imitation`` (1.0) pins gymnasium 0.29
and Stable-Baselines3 2.2 and pulls the old ``gym`` 0.21, which cannot live beside the
gymnasium 1.x / SB3 2.9 stack here. The loss is ``imitation``'s BC loss: the negative
log-likelihood of the expert's actions under the policy's distribution, minus a small entropy
bonus; for SAC/TD3 actors the mean squared error of the deterministic action (in the
policy's [-1, 1] scale), for DQN the cross-entropy of the Q-values.

An expert is named ``module:function``; ``function(env)`` is called at the start of each
episode with the (wrapped) environment and returns ``act(observation) -> action``, which may
keep its own phase between calls and read the environment.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable

import gymnasium as gym
import numpy as np
import torch
from stable_baselines3.common.policies import ActorCriticPolicy

ExpertFactory = Callable[[gym.Env], Callable[[np.ndarray], np.ndarray]]


def load_expert(name: str) -> ExpertFactory:
    """``module:function`` -> the function."""
    module, _, function = name.partition(":")
    if not function:
        raise ValueError(f"an expert is 'module:function', got {name!r}")
    return getattr(importlib.import_module(module), function)


def collect_expert(
    env: gym.Env, expert: ExpertFactory, episodes: int, seed: int = 0
) -> dict[str, np.ndarray]:
    """Roll out the expert: ``observations``, ``actions``, ``episode_starts`` (True at each
    episode's first step), ``returns`` (one per episode), ``successes``."""
    obs_list, act_list, starts, returns, successes = [], [], [], [], []
    for k in range(episodes):
        obs, _ = env.reset(seed=seed + k)
        act = expert(env)
        done, total, first, info = False, 0.0, True, {}
        while not done:
            action = np.asarray(act(obs))
            obs_list.append(np.asarray(obs).copy())
            act_list.append(action.copy())
            starts.append(first)
            first = False
            obs, reward, terminated, truncated, info = env.step(action)
            total += float(reward)
            done = terminated or truncated
        returns.append(total)
        successes.append(bool(info.get("is_success", False)))
    return {
        "observations": np.asarray(obs_list, dtype=np.float32),
        "actions": np.asarray(act_list),
        "episode_starts": np.asarray(starts),
        "returns": np.asarray(returns),
        "successes": np.asarray(successes),
    }


def successful_episodes(data: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The expert's data restricted to its successful episodes (an expert that sometimes
    fails spends most of its pairs failing: its failed episodes run to the time limit)."""
    successes = np.asarray(data["successes"], dtype=bool)
    if not successes.any():
        raise ValueError("the expert succeeded in none of its episodes: nothing to clone")
    episode = np.cumsum(data["episode_starts"]) - 1  # the episode of each pair
    keep = successes[episode]
    return {
        "observations": data["observations"][keep],
        "actions": data["actions"][keep],
        "episode_starts": data["episode_starts"][keep],
        "returns": data["returns"][successes],
        "successes": successes[successes],
    }


def _is_recurrent(policy) -> bool:
    return hasattr(policy, "lstm_actor")


def _loss(policy, obs: torch.Tensor, actions: torch.Tensor, ent_weight: float, starts=None):
    if _is_recurrent(policy):
        # One episode from zero states (behaviour_clone's chunks): its start resets states that
        # are zero already, so the LSTM may take the sequence in one call instead of a step at
        # a time (sb3-contrib's loop where a sequence holds a start; 8x faster on the Gripper's
        # episodes), and only the actor's LSTM runs (the critic's is not in the loss).
        lstm = policy.lstm_actor
        zeros = torch.zeros(lstm.num_layers, 1, lstm.hidden_size, device=obs.device)
        if starts is not None and not bool(starts[1:].any()):
            starts = torch.zeros_like(starts)
        distribution, _ = policy.get_distribution(obs, (zeros, zeros.clone()), starts)
        log_prob, entropy = distribution.log_prob(actions), distribution.entropy()
        return -log_prob.mean() - ent_weight * entropy.mean()
    if isinstance(policy, ActorCriticPolicy):
        _, log_prob, entropy = policy.evaluate_actions(obs, actions)
        entropy = entropy if entropy is not None else -log_prob
        return -log_prob.mean() - ent_weight * entropy.mean()
    if hasattr(policy, "q_net"):  # DQN
        return torch.nn.functional.cross_entropy(policy.q_net(obs), actions.long().flatten())
    # SAC / TD3: the deterministic action in the policy's [-1, 1] scale.
    target = torch.as_tensor(policy.scale_action(actions.cpu().numpy()), device=obs.device)
    return torch.nn.functional.mse_loss(policy.actor(obs, deterministic=True), target)


def _optimiser_parameters(policy):
    if hasattr(policy, "q_net"):
        return policy.q_net.parameters()
    if hasattr(policy, "actor") and not isinstance(policy, ActorCriticPolicy):
        return policy.actor.parameters()
    return policy.parameters()


def behaviour_clone(
    policy,
    observations: np.ndarray,
    actions: np.ndarray,
    *,
    epochs: int = 100,
    batch_size: int = 64,
    learning_rate: float = 1e-3,
    ent_weight: float = 1e-3,
    episode_starts: np.ndarray | None = None,
    seed: int = 0,
) -> list[float]:
    """Fit `policy` (an SB3 policy, in place) to the pairs; the mean loss of each epoch.

    Observations are what the policy sees (normalised if the run normalises). A recurrent
    policy is fitted one whole episode at a time (``episode_starts`` marks them), its LSTM
    starting from zeros like at a reset.
    """
    generator = torch.Generator().manual_seed(seed)
    device = policy.device
    obs = torch.as_tensor(observations, dtype=torch.float32, device=device)
    act = torch.as_tensor(actions, device=device)
    if act.dtype == torch.float64:
        act = act.float()
    optimiser = torch.optim.Adam(_optimiser_parameters(policy), lr=learning_rate)
    policy.set_training_mode(True)
    recurrent = _is_recurrent(policy)
    if recurrent:
        if episode_starts is None:
            raise ValueError("a recurrent policy needs the episode_starts of its data")
        bounds = [*np.flatnonzero(episode_starts), len(observations)]
        batches = [slice(a, b) for a, b in zip(bounds[:-1], bounds[1:], strict=True)]
        starts = torch.as_tensor(np.asarray(episode_starts, np.float32), device=device)
    history = []
    for _ in range(epochs):
        losses = []
        if recurrent:
            order = torch.randperm(len(batches), generator=generator).tolist()
            chunks = [(batches[i], starts[batches[i]]) for i in order]
        else:
            perm = torch.randperm(len(obs), generator=generator).to(device)
            chunks = [(perm[i : i + batch_size], None) for i in range(0, len(obs), batch_size)]
        for index, chunk_starts in chunks:
            loss = _loss(policy, obs[index], act[index], ent_weight, chunk_starts)
            optimiser.zero_grad()
            loss.backward()
            optimiser.step()
            losses.append(loss.item())
        history.append(float(np.mean(losses)))
    policy.set_training_mode(False)
    return history


def predict_actions(policy, observations: np.ndarray, episode_starts=None) -> np.ndarray:
    """The policy's deterministic actions on a data set (recurrent policies: run through each
    episode in order)."""
    if not _is_recurrent(policy):
        actions, _ = policy.predict(observations, deterministic=True)
        return actions
    out, state = [], None
    for o, s in zip(observations, episode_starts, strict=True):
        a, state = policy.predict(o, state=state, episode_start=np.array([s]), deterministic=True)
        out.append(a)
    return np.asarray(out)


def set_exploration(policy, std: float) -> None:
    """Set a Gaussian policy's state-independent standard deviation (SB3's ``log_std``) to
    `std` in every action dimension. Cloning a deterministic expert drives it towards zero
    (the log-likelihood of exact actions grows without bound as it shrinks: 0.014 after
    3000 epochs on the TrunkSpaceDebris pull), and PPO from such a policy breaks at its first
    update: each step of the mean is hundreds of standard deviations, the ratio's KL
    divergence runs to 1e4 and 99.7 % of the samples are clipped (measured,
    docs/learning.md). The mean, the cloned behaviour, is kept."""
    if not 0.0 < std < np.inf:
        raise ValueError(f"std must be a positive number, got {std!r}")
    log_std = getattr(policy, "log_std", None)
    if not isinstance(log_std, torch.nn.Parameter):
        raise ValueError(f"{type(policy).__name__} has no state-independent log_std to set")
    with torch.no_grad():
        log_std.fill_(float(np.log(std)))


def pretrain(model, config) -> dict:
    """`pliant train --bc-expert`: collect the expert's episodes, fit ``model.policy``, and
    report the fit (loss per epoch, agreement with the expert on its data). With VecNormalize,
    the observations of all the expert's episodes first update the normaliser (with
    ``successful_only``, the failed ones too: statistics of the successes alone can miss a
    whole feature's spread, e.g. a cube size the expert never catches, and the running
    statistics then move under the cloned policy as soon as RL meets it), then the cloned
    pairs are normalised as the policy will see them. ``std`` in the configuration sets the
    cloned policy's exploration (:func:`set_exploration`) before RL starts."""
    from pliant.learn.vec import make_env

    bc = {"episodes": 20, "epochs": 100, "batch_size": 64, "learning_rate": 1e-3, **config.bc}
    env = make_env(config.env_id, config.env_kwargs)
    try:
        data = collect_expert(env, load_expert(bc["expert"]), bc["episodes"], seed=config.seed)
    finally:
        env.close()
    expert_success = float(data["successes"].mean())
    vecnorm = model.get_vec_normalize_env()
    if vecnorm is not None and vecnorm.norm_obs:
        # every episode's states, failed ones included: they are what the policy will meet
        vecnorm.obs_rms.update(data["observations"])
    if bc.get("successful_only"):
        data = successful_episodes(data)
    observations = data["observations"]
    if vecnorm is not None and vecnorm.norm_obs:
        observations = vecnorm.normalize_obs(observations)
    history = behaviour_clone(
        model.policy,
        observations,
        data["actions"],
        epochs=bc["epochs"],
        batch_size=bc["batch_size"],
        learning_rate=bc["learning_rate"],
        episode_starts=data["episode_starts"],
        seed=config.seed,
    )
    predicted = predict_actions(model.policy, observations, data["episode_starts"])
    std = bc.get("std")
    if std is not None:
        set_exploration(model.policy, float(std))
    return {
        "expert": bc["expert"],
        "pairs": len(observations),
        "expert_episodes": int(bc["episodes"]),
        "episodes_cloned": len(data["returns"]),
        "expert_mean_return": float(data["returns"].mean()),
        "expert_success_rate": expert_success,
        "loss_first_epoch": history[0],
        "loss_last_epoch": history[-1],
        "std_after": std,
        **agreement(predicted, data["actions"]),
    }


def agreement(predicted: np.ndarray, expert: np.ndarray) -> dict:
    """How well cloned actions match the expert's: the fraction equal (discrete) or the mean
    absolute error (continuous)."""
    predicted = np.asarray(predicted).reshape(len(expert), -1)
    expert = np.asarray(expert).reshape(len(expert), -1)
    if np.issubdtype(expert.dtype, np.integer):
        return {"action_accuracy": float(np.mean(np.all(predicted == expert, axis=1)))}
    return {"action_mean_abs_error": float(np.mean(np.abs(predicted - expert)))}
