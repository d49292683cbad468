"""Training configurations: YAML files that map one to one onto :class:`TrainConfig` and, under
``hyperparams``, onto the Stable-Baselines3 algorithm's constructor.

A file holds one section per algorithm (``SAC:``, ``PPO:``, ...) or the fields of one run at
its top level::

    SAC:
      total_timesteps: 200000
      n_envs: 2
      hyperparams:              # SAC(**hyperparams)
        policy: MlpPolicy
        learning_rate: 3.0e-4
        policy_kwargs:
          net_arch: [512, 512, 512]
          activation_fn: ReLU   # a torch.nn class by name

Configurations merge in this order, later winning: ``configs/default.yaml`` (the algorithm's
section), ``configs/<EnvName>.yaml`` (the thesis' settings for that environment, where there is
one), the user's file, the command line. In ``hyperparams``, ``learning_rate: lin_3e-4`` is a
rate decaying linearly to 0 (the RL Zoo's notation); ``policy_kwargs.activation_fn`` and
``optimizer_class`` name a ``torch.nn``/``torch.optim`` class.
"""

from __future__ import annotations

import copy
import dataclasses
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from pliant.errors import CorruptFileError, TrainingError
from pliant.files import atomic_path, read_checked

CONFIG_DIR = Path(__file__).parent / "configs"
ALGOS = ("PPO", "SAC", "TD3", "A2C", "DQN", "RecurrentPPO")
OFF_POLICY = ("SAC", "TD3", "DQN")


@dataclass
class TrainConfig:
    """One training run. Steps are environment steps, summed over the workers."""

    env_id: str
    algo: str = "PPO"
    total_timesteps: int = 100_000
    seed: int = 0
    #: keyword arguments of the environment (``gymnasium.make(env_id, **env_kwargs)``).
    env_kwargs: dict = field(default_factory=dict)
    #: environments stepped in parallel; ``vec_env``: "subproc" (spawned worker processes),
    #: "dummy" (in this process) or "ray" (Ray actors; ``ray_address``: "auto", an address,
    #: or None for a local Ray started here).
    n_envs: int = 1
    vec_env: str = "subproc"
    ray_address: str | None = None
    #: VecNormalize of observations and rewards: False, True or VecNormalize's keyword
    #: arguments; its statistics are saved with every checkpoint and the final model.
    normalize: bool | dict = False
    #: evaluation every ``eval_freq`` steps on ``eval_episodes`` episodes (deterministic
    #: policy, a fixed seed: the same tasks every time); ``eval_env_kwargs`` default to
    #: ``env_kwargs``.
    eval_freq: int = 10_000
    eval_episodes: int = 10
    eval_env_kwargs: dict | None = None
    #: a checkpoint every ``checkpoint_freq`` steps; the last ``keep_checkpoints`` are kept.
    checkpoint_freq: int = 10_000
    keep_checkpoints: int = 2
    #: evaluation episodes recorded as a GIF at the end (0: none).
    video_episodes: int = 1
    device: str = "cpu"
    #: keyword arguments of the SB3 algorithm (``policy`` included).
    hyperparams: dict = field(default_factory=dict)
    #: the learner's updates without the time that is not their arithmetic
    #: (:mod:`pliant.learn.updates`: SAC's critics skip weight gradients nobody reads, same
    #: results to the bit; Adam fused, same up to round-off); False: SB3's own, as they were.
    fast_updates: bool = True
    #: behaviour-cloning pre-training (:mod:`pliant.learn.bc`): ``expert`` ("module:function"),
    #: ``epochs``, ``episodes``, ``batch_size``, ``learning_rate``, ``successful_only`` (clone
    #: the expert's successful episodes only), ``std`` (the cloned policy's exploration).
    bc: dict | None = None

    def __post_init__(self) -> None:
        if self.algo not in ALGOS:
            raise ValueError(f"algo must be one of {', '.join(ALGOS)}, got {self.algo!r}")
        if self.n_envs < 1:
            raise ValueError(f"n_envs must be >= 1, got {self.n_envs}")
        if self.vec_env not in ("subproc", "dummy", "ray"):
            raise ValueError(f"vec_env must be 'subproc', 'dummy' or 'ray', got {self.vec_env!r}")
        if self.bc is not None:
            _check_bc(self.bc)

    @property
    def env_name(self) -> str:
        """``pliant/Trunk-v0`` -> ``Trunk``."""
        return self.env_id.split("/")[-1].rsplit("-v", 1)[0]

    def to_dict(self) -> dict:
        return dataclasses.asdict(self)

    def save(self, path: Path) -> None:
        text = yaml.safe_dump(_plain(self.to_dict()), sort_keys=False)
        with atomic_path(path) as tmp:  # what --resume reads: never half written
            tmp.write_text(text)

    @classmethod
    def load(cls, path: Path) -> TrainConfig:
        """Raises CorruptFileError when the file is not a readable configuration."""

        path = Path(path)
        data = _read_yaml(path, CorruptFileError)
        try:
            return cls(**data)
        except TypeError as exc:  # unknown settings
            raise CorruptFileError(f"{path}: not a training configuration: {exc}", path) from exc


BC_KEYS = ("expert", "epochs", "episodes", "batch_size", "learning_rate", "successful_only", "std")


def _check_bc(bc) -> None:
    """The behaviour-cloning settings, refused here rather than after the expert's episodes
    have been collected."""
    if not isinstance(bc, dict):
        raise ValueError(f"bc must be a mapping of {', '.join(BC_KEYS)}, got {bc!r}")
    unknown = set(bc) - set(BC_KEYS)
    if unknown:
        raise ValueError(f"unknown bc settings {sorted(unknown)}; known: {', '.join(BC_KEYS)}")
    if not isinstance(bc.get("expert"), str) or ":" not in bc["expert"]:
        raise ValueError(f"bc.expert must be 'module:function', got {bc.get('expert')!r}")
    for key in ("epochs", "episodes", "batch_size"):
        value = bc.get(key, 1)
        if isinstance(value, bool) or not isinstance(value, int) or value < 1:
            raise ValueError(f"bc.{key} must be an integer >= 1, got {value!r}")
    for key in ("learning_rate", "std"):  # absent: pretrain's default rate, the cloned std
        value = bc.get(key)
        if value is None:
            continue
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise ValueError(f"bc.{key} must be a number > 0, got {value!r}")
        if not (math.isfinite(value) and value > 0):
            raise ValueError(f"bc.{key} must be a finite number > 0, got {value!r}")


def _plain(value):
    """YAML-safe: tuples (e.g. an environment's ``cube_sizes``) become lists."""
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_plain(v) for v in value]
    return value


def deep_merge(base: dict, update: dict) -> dict:
    """`update` over `base`, dictionaries merged key by key (lists and values replaced)."""
    out = copy.deepcopy(base)
    for key, value in update.items():
        if isinstance(value, dict) and isinstance(out.get(key), dict):
            out[key] = deep_merge(out[key], value)
        else:
            out[key] = copy.deepcopy(value)
    return out


def _section(data: dict | None, algo: str) -> dict:
    """The algorithm's section of a configuration file, or the file's top level if it has no
    algorithm sections."""
    if not data:
        return {}
    if any(key in ALGOS for key in data):
        return data.get(algo) or {}
    return data


def _read_yaml(
    path: Path, error: type | None = None, what: str = "a training configuration (YAML)"
) -> dict:
    """The mapping of a YAML file (`what` it should be); a file that is not one raises
    `error` (default TrainingError) naming it."""

    def read(p: Path) -> dict:
        try:
            data = yaml.safe_load(p.read_text())
        except yaml.YAMLError as exc:  # its text spans lines: the CLI's error is one
            mark = getattr(exc, "problem_mark", None)
            where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
            raise ValueError(f"{getattr(exc, 'problem', None) or exc}{where}") from exc
        if not isinstance(data, dict):
            raise ValueError(f"a YAML mapping was expected, got {type(data).__name__}")
        return data

    return read_checked(path, read, what, error or TrainingError)


def load_config(
    env_id: str,
    algo: str,
    path: str | Path | None = None,
    overrides: dict[str, Any] | None = None,
) -> TrainConfig:
    """The run's configuration: defaults, the environment's file, `path`, then `overrides`
    (module docstring)."""
    fields = {f.name for f in dataclasses.fields(TrainConfig)}
    merged: dict = {}
    env_name = env_id.split("/")[-1].rsplit("-v", 1)[0]
    sources = [CONFIG_DIR / "default.yaml", CONFIG_DIR / f"{env_name}.yaml"]
    for source in sources:
        if source.exists():
            merged = deep_merge(merged, _section(yaml.safe_load(source.read_text()), algo))
    if path is not None:
        merged = deep_merge(merged, _section(_read_yaml(Path(path)), algo))
    merged = deep_merge(merged, {k: v for k, v in (overrides or {}).items() if v is not None})
    unknown = set(merged) - fields
    if unknown:
        raise ValueError(
            f"unknown training settings {sorted(unknown)}: SB3 arguments go under 'hyperparams'"
        )
    merged.update(env_id=env_id, algo=algo)
    return TrainConfig(**merged)


def linear_schedule(initial: float):
    def schedule(progress_remaining: float) -> float:
        return progress_remaining * initial

    return schedule


def sb3_kwargs(hyperparams: dict) -> dict:
    """SB3 constructor arguments from YAML values: class names to classes, ``lin_<value>``
    learning rates to linear schedules."""
    import torch

    kwargs = copy.deepcopy(hyperparams)
    for key in ("learning_rate", "clip_range"):
        value = kwargs.get(key)
        if isinstance(value, str) and value.startswith("lin_"):
            kwargs[key] = linear_schedule(float(value[4:]))
    policy_kwargs = kwargs.get("policy_kwargs") or {}
    if isinstance(policy_kwargs.get("activation_fn"), str):
        policy_kwargs["activation_fn"] = getattr(torch.nn, policy_kwargs["activation_fn"])
    if isinstance(policy_kwargs.get("optimizer_class"), str):
        policy_kwargs["optimizer_class"] = getattr(torch.optim, policy_kwargs["optimizer_class"])
    if policy_kwargs:
        kwargs["policy_kwargs"] = policy_kwargs
    for key in ("train_freq",):
        if isinstance(kwargs.get(key), list):
            kwargs[key] = tuple(kwargs[key])
    return kwargs
