"""Kept policies: what acting needs of a Stable-Baselines3 model, in one small file.

A training run's ``model.zip`` holds the critic, the optimiser's state and the run's settings
besides the actor: a 3×512 PPO's is about 13 MB. What re-evaluating a headline figure needs is
the actor alone, and the observation normaliser it was trained behind: :func:`export_policy`
writes that (float32 weights) to a ``.npz`` file, about 2.1 MB for the same PPO, and
:func:`load_policy` reads it back as a :class:`KeptPolicy` whose ``predict`` gives SB3's
``model.predict`` actions (deterministic: the same actions; sampled: the same distribution, and
the same samples under the same ``torch`` seed).

The file (NumPy's ``savez_compressed``, no pickles; each member CRC-checked on reading)::

    meta               the JSON below, as UTF-8 bytes
    observation_low/high, action_low/high    the Box spaces' bounds
    obs_mean, obs_var  VecNormalize's observation statistics, where the run used one
    trunk.I.weight/bias, mean.I.*, log_std.I.*   the Linear layers of each sequence
    log_std            PPO's and A2C's state-independent log standard deviation (Box actions)
    lstm.*             RecurrentPPO's actor LSTM (torch's weight_ih_l0, weight_hh_l0, ...)

``meta``: ``format``, ``version``, ``algo``, ``kind`` (``diag_gaussian``: PPO, A2C or
RecurrentPPO on Box actions, clipped to the bounds; ``categorical``: the same on Discrete ones;
``squashed_gaussian``: SAC; ``deterministic``: TD3's tanh actor; ``greedy``: DQN's Q-network),
``layers`` (each sequence's modules in order: ``linear`` or a ``torch.nn`` activation's name),
``observation_space``, ``action_space``, ``normalize`` (VecNormalize's ``clip_obs`` and
``epsilon``, or null), ``lstm`` (RecurrentPPO's actor LSTM: ``input_size``, ``hidden_size``,
``num_layers``; null for the others; version 2 of the format) and ``provenance`` (what the
exporter was given: the environment, the run's configuration, seed, step and source).

A recurrent policy (sb3-contrib's RecurrentPPO) is kept with its actor's LSTM: ``predict``
takes and returns the LSTM's state and resets it where ``episode_start`` says, as
RecurrentPPO's ``predict`` does (the critic's LSTM is not kept: acting does not use it).
State-dependent exploration (gSDE), image and dictionary observations are not kept (a
:class:`~pliant.errors.PolicyError` says so at export).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch
from gymnasium import spaces

from pliant.errors import PolicyError
from pliant.files import load_npz, read_checked, save_npz

FORMAT = "pliant-kept-policy"
VERSION = 2  # 2: RecurrentPPO's actor LSTM (``lstm``); files without one are written as 1
READABLE = (1, 2)
KINDS = ("diag_gaussian", "categorical", "squashed_gaussian", "deterministic", "greedy")
# SB3's clamp of SAC's log standard deviation (stable_baselines3.sac.policies)
LOG_STD_MIN, LOG_STD_MAX = -20.0, 2.0
# The parameter-free layers kept by name (rebuilt with their default arguments, as SB3 builds
# its ``activation_fn``): torch's activations, Identity and Flatten.
_NAMED = (
    frozenset(torch.nn.modules.activation.__all__) - {"MultiheadAttention", "PReLU", "Threshold"}
) | {"Identity", "Flatten"}


def _sequence(module: torch.nn.Module, name: str, arrays: dict) -> list[str]:
    """A Sequential (or one Linear) as layer names, its Linear weights added to `arrays`."""
    modules = list(module) if isinstance(module, torch.nn.Sequential) else [module]
    layers = []
    for i, layer in enumerate(modules):
        if isinstance(layer, torch.nn.Linear):
            arrays[f"{name}.{i}.weight"] = layer.weight.detach().cpu().numpy().astype(np.float32)
            bias = layer.bias if layer.bias is not None else torch.zeros(layer.out_features)
            arrays[f"{name}.{i}.bias"] = bias.detach().cpu().numpy().astype(np.float32)
            layers.append("linear")
        elif (
            type(layer).__name__ in _NAMED
            and not any(True for _ in layer.parameters())
            and repr(layer) == repr(type(layer)())  # its default arguments: rebuilt by name
        ):
            layers.append(type(layer).__name__)  # an activation: Tanh, ReLU, SiLU, ...
        else:
            raise PolicyError(f"{name}: a {type(layer).__name__} layer cannot be kept")
    return layers


def _space(space) -> tuple[dict, dict]:
    """A space's JSON description and its arrays (Box bounds)."""
    if isinstance(space, spaces.Box):
        return {"type": "Box", "shape": list(space.shape), "dtype": str(space.dtype)}, {
            "low": space.low,
            "high": space.high,
        }
    if isinstance(space, spaces.Discrete):
        return {"type": "Discrete", "n": int(space.n), "start": int(space.start)}, {}
    raise PolicyError(f"a {type(space).__name__} space cannot be kept (Box or Discrete)")


def _lstm(model, algo: str, arrays: dict) -> dict | None:
    """RecurrentPPO's actor LSTM added to `arrays` (``lstm.weight_ih_l0``, ...) and described;
    None for a feed-forward policy."""
    if algo != "RecurrentPPO":
        return None
    lstm = model.policy.lstm_actor
    if lstm.bidirectional or lstm.proj_size or not lstm.bias or lstm.batch_first:
        raise PolicyError("only a plain LSTM (one direction, biases, no projection) is kept")
    for name, value in lstm.state_dict().items():
        arrays[f"lstm.{name}"] = value.detach().cpu().numpy().astype(np.float32)
    return {
        "input_size": lstm.input_size,
        "hidden_size": lstm.hidden_size,
        "num_layers": lstm.num_layers,
    }


def _actor(model, algo: str, arrays: dict) -> tuple[str, dict]:
    """The acting networks of `model`: its kind and each sequence's layers."""
    from stable_baselines3.common.torch_layers import FlattenExtractor

    policy = model.policy
    if getattr(policy, "use_sde", False):
        raise PolicyError(f"{algo} with state-dependent exploration (gSDE) cannot be kept")
    if algo in ("PPO", "A2C", "RecurrentPPO"):
        features = policy.pi_features_extractor
        layers = {"trunk": _sequence(policy.mlp_extractor.policy_net, "trunk", arrays)}
        layers["mean"] = _sequence(policy.action_net, "mean", arrays)
        if isinstance(model.action_space, spaces.Box):
            arrays["log_std"] = policy.log_std.detach().cpu().numpy().astype(np.float32)
            kind = "diag_gaussian"
        elif isinstance(model.action_space, spaces.Discrete):
            kind = "categorical"
        else:
            raise PolicyError(f"{algo} on a {type(model.action_space).__name__} action space")
    elif algo == "SAC":
        actor = policy.actor
        features = actor.features_extractor
        layers = {"trunk": _sequence(actor.latent_pi, "trunk", arrays)}
        layers["mean"] = _sequence(actor.mu, "mean", arrays)
        layers["log_std"] = _sequence(actor.log_std, "log_std", arrays)
        kind = "squashed_gaussian"
    elif algo == "TD3":
        features = policy.actor.features_extractor
        layers, kind = {"trunk": _sequence(policy.actor.mu, "trunk", arrays)}, "deterministic"
    elif algo == "DQN":
        features = policy.q_net.features_extractor
        layers, kind = {"trunk": _sequence(policy.q_net.q_net, "trunk", arrays)}, "greedy"
    else:
        raise PolicyError(
            f"a {algo} policy cannot be kept (PPO, A2C, RecurrentPPO, SAC, TD3 or DQN)"
        )
    if not isinstance(features, FlattenExtractor):
        raise PolicyError(f"a {type(features).__name__} features extractor cannot be kept")
    return kind, layers


def export_policy(
    model,
    path: str | Path,
    *,
    algo: str | None = None,
    vecnormalize=None,
    provenance: dict | None = None,
) -> Path:
    """Write what acting needs of the SB3 `model` to `path` (``.npz``), atomically.

    Args:
        model: a PPO, A2C, SAC, TD3 or DQN model with an MLP policy, or a RecurrentPPO
            model with an LSTM one.
        algo: its algorithm (default: the model's class name).
        vecnormalize: the VecNormalize the model was trained behind, if any (its observation
            statistics are kept; rewards are not normalised when acting).
        provenance: what to record with it (JSON): the environment (``env_id``,
            ``env_kwargs``), the run's configuration, seed, step, source.

    Returns:
        The path written.
    """
    algo = algo or type(model).__name__
    observation, obs_bounds = _space(model.observation_space)
    if observation["type"] != "Box" or model.observation_space.dtype == np.uint8:
        raise PolicyError("only float Box observations are kept (no images, no Discrete)")
    action, act_bounds = _space(model.action_space)
    arrays: dict[str, np.ndarray] = {}
    kind, layers = _actor(model, algo, arrays)
    lstm = _lstm(model, algo, arrays)
    arrays.update({f"observation_{k}": v for k, v in obs_bounds.items()})
    arrays.update({f"action_{k}": v for k, v in act_bounds.items()})
    normalize = None
    if vecnormalize is not None and getattr(vecnormalize, "norm_obs", True):
        rms = vecnormalize.obs_rms
        if isinstance(rms, dict):
            raise PolicyError("dictionary observation statistics cannot be kept")
        arrays["obs_mean"], arrays["obs_var"] = np.asarray(rms.mean), np.asarray(rms.var)
        normalize = {"clip_obs": float(vecnormalize.clip_obs), "epsilon": vecnormalize.epsilon}
    meta = {
        "format": FORMAT,
        "version": VERSION if lstm else 1,
        "algo": algo,
        "kind": kind,
        "layers": layers,
        "lstm": lstm,
        "observation_space": observation,
        "action_space": action,
        "normalize": normalize,
        "provenance": {
            "step": int(getattr(model, "num_timesteps", 0)),
            "seed": getattr(model, "seed", None),
            **(provenance or {}),
        },
    }
    text = json.dumps(meta, default=str)
    arrays["meta"] = np.frombuffer(text.encode(), dtype=np.uint8)
    return save_npz(path, compressed=True, **arrays)


class _Sequence(torch.nn.Module):
    def __init__(self, layers: list[str], name: str, arrays: dict) -> None:
        super().__init__()
        modules = []
        for i, layer in enumerate(layers):
            if layer == "linear":
                weight = torch.from_numpy(np.array(arrays[f"{name}.{i}.weight"], np.float32))
                bias = torch.from_numpy(np.array(arrays[f"{name}.{i}.bias"], np.float32))
                if weight.ndim != 2 or bias.shape != weight.shape[:1]:
                    raise ValueError(
                        f"{name}.{i}: weight {tuple(weight.shape)}, bias {tuple(bias.shape)}"
                    )
                linear = torch.nn.Linear(weight.shape[1], weight.shape[0])
                linear.weight.data, linear.bias.data = weight, bias
                modules.append(linear)
            elif layer in _NAMED:
                modules.append(getattr(torch.nn, layer)())
            else:
                raise ValueError(f"{name}.{i}: unknown layer {layer!r}")
        self.net = torch.nn.Sequential(*modules)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.net(x)


def _space_from(description: dict, low=None, high=None):
    if description["type"] == "Box":
        return spaces.Box(low, high, tuple(description["shape"]), np.dtype(description["dtype"]))
    if description["type"] == "Discrete":
        return spaces.Discrete(int(description["n"]), start=int(description["start"]))
    raise ValueError(f"unknown space {description['type']!r}")


@dataclass
class ObservationNormalizer:
    """VecNormalize's observation statistics: ``normalize_obs`` as VecNormalize computes it."""

    mean: np.ndarray
    var: np.ndarray
    clip_obs: float
    epsilon: float
    training: bool = field(default=False, repr=False)

    def normalize_obs(self, obs):
        obs = np.asarray(obs)
        normed = (obs - self.mean) / np.sqrt(self.var + self.epsilon)
        return np.clip(normed, -self.clip_obs, self.clip_obs).astype(np.float32)


class KeptPolicy:
    """A kept policy (see the module's docstring): ``predict`` acts on raw observations (the
    normaliser, where there is one, applied first) as SB3's ``model.predict`` does on
    normalised ones; ``env_id``, ``env_kwargs`` and ``provenance`` say where it comes from;
    ``lstm`` is a recurrent policy's actor LSTM (None for the others)."""

    def __init__(self, meta: dict, arrays: dict, path: Path) -> None:
        self.path = path
        self.meta = meta
        self.algo: str = meta["algo"]
        self.kind: str = meta["kind"]
        if self.kind not in KINDS:
            raise ValueError(f"unknown kind {self.kind!r}")
        self.provenance: dict = meta.get("provenance") or {}
        self.env_id: str | None = self.provenance.get("env_id")
        self.env_kwargs: dict = self.provenance.get("env_kwargs") or {}
        obs, act = meta["observation_space"], meta["action_space"]
        self.observation_space = _space_from(
            obs, arrays.get("observation_low"), arrays.get("observation_high")
        )
        self.action_space = _space_from(act, arrays.get("action_low"), arrays.get("action_high"))
        self.networks = {
            name: _Sequence(layers, name, arrays) for name, layers in meta["layers"].items()
        }
        self.lstm = _lstm_from(meta.get("lstm"), arrays)
        self.log_std = None
        if self.kind == "diag_gaussian":
            self.log_std = torch.from_numpy(np.array(arrays["log_std"], np.float32))
        self.normalizer = None
        if meta.get("normalize"):
            norm = meta["normalize"]
            self.normalizer = ObservationNormalizer(
                np.asarray(arrays["obs_mean"]),
                np.asarray(arrays["obs_var"]),
                float(norm["clip_obs"]),
                float(norm["epsilon"]),
            )
        self._check()

    def _check(self) -> None:
        """Each network's input and output against the spaces (a file that loads but does
        not fit its own description is corrupt)."""
        x = torch.zeros((1, int(np.prod(self.observation_space.shape))))
        if self.lstm is not None and self.lstm.input_size != x.shape[1]:
            raise ValueError(f"its LSTM takes {self.lstm.input_size} inputs, not {x.shape[1]}")
        with torch.no_grad():
            out = self._distribution_params(self._recur(x, None, None)[0])
        width = (
            int(self.action_space.n)
            if isinstance(self.action_space, spaces.Discrete)
            else int(np.prod(self.action_space.shape))
        )
        if out[0].shape != (1, width):
            raise ValueError(f"its networks give {tuple(out[0].shape)} for actions of {width}")

    def _distribution_params(self, x: torch.Tensor):
        latent = self.networks["trunk"](x)
        if self.kind in ("deterministic", "greedy"):
            return (latent,)
        mean = self.networks["mean"](latent)
        if self.kind == "diag_gaussian":
            return mean, self.log_std
        if self.kind == "squashed_gaussian":
            log_std = torch.clamp(self.networks["log_std"](latent), LOG_STD_MIN, LOG_STD_MAX)
            return mean, log_std
        return (mean,)  # categorical: logits

    def _recur(self, x: torch.Tensor, state, episode_start):
        """The actor LSTM's output for one step of ``len(x)`` environments from `state` (zeros
        where None; reset where `episode_start`), and its next state; `x` itself and None for
        a feed-forward policy."""
        if self.lstm is None:
            return x, None
        n = len(x)
        shape = (self.lstm.num_layers, n, self.lstm.hidden_size)
        if state is None:
            h = c = torch.zeros(shape)
        else:
            try:
                h, c = (torch.as_tensor(np.asarray(s), dtype=torch.float32) for s in state)
            except (TypeError, ValueError) as exc:
                raise PolicyError(f"{self.path}: the LSTM state is not (h, c): {exc}") from None
            if h.shape != shape or c.shape != shape:
                raise PolicyError(
                    f"{self.path}: an LSTM state of shapes {tuple(h.shape)}, {tuple(c.shape)};"
                    f" for {n} observation(s) it is {shape}"
                )
        if episode_start is not None:
            start = np.asarray(episode_start, dtype=np.float32).reshape(-1)
            if start.shape != (n,):
                raise PolicyError(
                    f"{self.path}: {start.size} episode_start flag(s) for {n} observation(s)"
                )
            keep = (1.0 - torch.from_numpy(start)).reshape(1, n, 1)
            h, c = keep * h, keep * c
        out, (h, c) = self.lstm(x[None], (h, c))  # a sequence of one step
        return out[0], (h.numpy(), c.numpy())

    def normalize_obs(self, obs):
        """The observation as the policy's networks take it (normalised where it was)."""
        return obs if self.normalizer is None else self.normalizer.normalize_obs(obs)

    def _batch(self, obs) -> tuple[np.ndarray, bool]:
        try:
            obs = np.asarray(obs, dtype=np.float64)
        except (TypeError, ValueError) as exc:
            raise PolicyError(f"{self.path}: the observation is not an array: {exc}") from None
        shape = tuple(self.observation_space.shape)
        if obs.shape == shape:
            obs, batched = obs[None], False
        elif obs.shape[1:] == shape:
            batched = True
        else:
            raise PolicyError(
                f"{self.path}: an observation of shape {obs.shape}; this policy takes {shape}"
                f" (or a batch: (n, {', '.join(map(str, shape))}))"
            )
        if not np.all(np.isfinite(obs)):
            raise PolicyError(f"{self.path}: the observation holds NaN or infinite values")
        return obs, batched

    def predict(
        self,
        observation,
        state=None,
        episode_start=None,
        deterministic: bool = True,
        *,
        normalized: bool = False,
    ):
        """``(action, state)`` for a raw observation (or a batch) as SB3's ``predict`` gives:
        `state` None, except a recurrent policy's LSTM state ``(h, c)``, which the next call
        takes (`episode_start`, one flag per observation, resets it);
        ``normalized=True``: the observation is already normalised (SB3's own convention)."""
        obs, batched = self._batch(observation)
        if not normalized:
            obs = self.normalize_obs(obs)
        x = torch.as_tensor(obs).float().reshape(len(obs), -1)  # SB3: Box obs .float(), flat
        with torch.no_grad():
            latent, state = self._recur(x, state, episode_start)
            params = self._distribution_params(latent)
            actions = self._act(params, deterministic)
        actions = actions.cpu().numpy().reshape((-1, *self.action_space.shape))
        if isinstance(self.action_space, spaces.Box):
            if self.kind in ("squashed_gaussian", "deterministic"):
                low, high = self.action_space.low, self.action_space.high
                actions = low + 0.5 * (actions + 1.0) * (high - low)
            else:
                actions = np.clip(actions, self.action_space.low, self.action_space.high)
        return (actions if batched else actions.squeeze(axis=0)), state

    def _act(self, params, deterministic: bool) -> torch.Tensor:
        if self.kind == "deterministic":
            return params[0]
        if self.kind == "greedy":
            if not deterministic:
                raise PolicyError("a kept DQN acts greedily only (deterministic=True)")
            return params[0].argmax(dim=1).reshape(-1)
        if self.kind == "categorical":
            dist = torch.distributions.Categorical(logits=params[0])
            return torch.argmax(dist.probs, dim=1) if deterministic else dist.sample()
        mean, log_std = params
        if deterministic:
            out = mean
        else:
            std = torch.ones_like(mean) * log_std.exp()
            out = torch.distributions.Normal(mean, std).rsample()
        return torch.tanh(out) if self.kind == "squashed_gaussian" else out


def _lstm_from(description: dict | None, arrays: dict) -> torch.nn.LSTM | None:
    if description is None:
        return None
    lstm = torch.nn.LSTM(
        int(description["input_size"]),
        int(description["hidden_size"]),
        num_layers=int(description["num_layers"]),
    )
    state = {
        name: torch.from_numpy(np.array(arrays[f"lstm.{name}"], np.float32))
        for name in lstm.state_dict()
    }
    lstm.load_state_dict(state)  # RuntimeError for a weight of the wrong shape
    return lstm.eval()


def load_policy(path: str | Path) -> KeptPolicy:
    """The kept policy in `path` (a ``.npz`` written by :func:`export_policy`).

    Raises:
        CorruptFileError: the file is empty, truncated, corrupt, not a kept policy or of a
            newer version, or its networks do not fit its spaces.
    """
    path = Path(path)
    arrays = load_npz(path, "a kept policy (.npz)")

    def parse(p: Path) -> KeptPolicy:
        meta = json.loads(bytes(arrays["meta"]).decode())
        if meta.get("format") != FORMAT:
            raise ValueError(f"format {meta.get('format')!r}, not {FORMAT!r}")
        if meta.get("version") not in READABLE:
            raise ValueError(
                f"version {meta.get('version')!r}; this Pliant reads {READABLE[-1]} and older"
            )
        return KeptPolicy(meta, arrays, p)

    return read_checked(path, parse, "a kept policy")
