"""Evaluation of a policy: success rate, returns, a GIF of episodes; loading saved models."""

from __future__ import annotations

import json
import pickle
import warnings
import zipfile
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import yaml

from pliant.errors import CheckpointWarning, CorruptFileError, PolicyError, TrainingError
from pliant.files import atomic_path, check_manifest, read_checked, write_json
from pliant.learn.config import ALGOS
from pliant.learn.vec import make_env

if TYPE_CHECKING:
    from pliant.learn.kept import KeptPolicy


#: The file name of a kept policy in a folder (:mod:`pliant.learn.kept`).
KEPT = "policy.npz"


@dataclass
class Evaluation:
    episodes: int
    success_rate: float | None  # None when the task has no success flag
    mean_return: float
    std_return: float
    mean_length: float
    diverged: int
    returns: list[float] = field(default_factory=list)
    successes: list[bool] = field(default_factory=list)

    def to_dict(self, per_episode: bool = False) -> dict:
        out = asdict(self)
        if not per_episode:
            del out["returns"], out["successes"]
        return out


def algorithm_class(algo: str):
    if algo not in ALGOS:
        raise ValueError(f"algo must be one of {', '.join(ALGOS)}, got {algo!r}")
    if algo == "RecurrentPPO":
        from sb3_contrib import RecurrentPPO

        return RecurrentPPO
    import stable_baselines3

    return getattr(stable_baselines3, algo)


def run_episodes(
    model,
    env,
    n_episodes: int,
    *,
    normalize_obs=None,
    deterministic: bool = True,
    seed: int | None = 0,
    frames: list | None = None,
    frame_episodes: int = 0,
) -> Evaluation:
    """Run `n_episodes` of `model` on a single (non-vectorised) `env`. `normalize_obs`: the
    training VecNormalize's ``normalize_obs`` where there was one. Episode k is reset with seed
    ``seed + k`` (the same tasks at every evaluation). Frames of the first `frame_episodes`
    episodes are appended to `frames` (``env`` made with ``render_mode="rgb_array"``)."""
    returns, lengths, successes, diverged = [], [], [], 0
    has_success = False
    for k in range(n_episodes):
        obs, _ = env.reset(seed=None if seed is None else seed + k)
        state, start = None, np.ones((1,), dtype=bool)
        total, length, done, info = 0.0, 0, False, {}
        if frames is not None and k < frame_episodes:
            frames.append(env.render())
        while not done:
            x = normalize_obs(obs) if normalize_obs is not None else obs
            action, state = model.predict(
                x, state=state, episode_start=start, deterministic=deterministic
            )
            start = np.zeros((1,), dtype=bool)
            obs, reward, terminated, truncated, info = env.step(action)
            total += float(reward)
            length += 1
            done = terminated or truncated
            if frames is not None and k < frame_episodes:
                frames.append(env.render())
        returns.append(total)
        lengths.append(length)
        if "is_success" in info:
            has_success = True
        successes.append(bool(info.get("is_success", False)))
        diverged += bool(info.get("diverged"))
    return Evaluation(
        episodes=n_episodes,
        success_rate=float(np.mean(successes)) if has_success else None,
        mean_return=float(np.mean(returns)),
        std_return=float(np.std(returns)),
        mean_length=float(np.mean(lengths)),
        diverged=diverged,
        returns=returns,
        successes=successes,
    )


@dataclass
class SavedPolicy:
    """A saved model with what is needed to run it: the algorithm, the environment it was
    trained on and its observation normaliser."""

    model: object
    algo: str
    env_id: str | None
    env_kwargs: dict
    vecnormalize: object | None

    @property
    def normalize_obs(self):
        return None if self.vecnormalize is None else self.vecnormalize.normalize_obs


def save_policy(model, folder: Path, algo: str, env_id: str, env_kwargs: dict, vecnorm) -> None:
    """model.zip, vecnormalize.pkl (if any) and meta.json in `folder`, each written
    atomically (a run killed while it saves its best model keeps the previous one)."""
    folder.mkdir(parents=True, exist_ok=True)
    with atomic_path(folder / "model.zip") as tmp:
        model.save(tmp)
    if vecnorm is not None:
        with atomic_path(folder / "vecnormalize.pkl") as tmp:
            vecnorm.save(str(tmp))
    meta = {"algo": algo, "env_id": env_id, "env_kwargs": env_kwargs}
    write_json(folder / "meta.json", meta)


class _NormalisedInput:
    """A kept policy acting on normalised observations, as an SB3 model does."""

    def __init__(self, policy: KeptPolicy) -> None:
        self.policy = policy

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        return self.policy.predict(
            observation, state, episode_start, deterministic=deterministic, normalized=True
        )


def _kept(path: Path, algo: str | None) -> SavedPolicy:
    from pliant.learn import kept  # PyTorch, on first use

    policy = kept.load_policy(path)
    if algo is not None and algo != policy.algo:
        raise PolicyError(f"{path}: a kept {policy.algo} policy, not {algo}")
    return SavedPolicy(
        _NormalisedInput(policy), policy.algo, policy.env_id, policy.env_kwargs, policy.normalizer
    )


def load_policy(path: str | Path, algo: str | None = None, device: str = "cpu") -> SavedPolicy:
    """A model saved by training: a ``model.zip``, the folder holding it, or a run folder
    (its ``final/``, else its newest intact checkpoint: damaged newer ones are skipped with a
    CheckpointWarning naming them); or a kept policy (:mod:`pliant.learn.kept`): a
    ``policy.npz``, or a folder holding one and no ``model.zip``. Its ``model.predict`` takes
    normalised observations (``normalize_obs``), as an SB3 model's.

    Raises:
        CorruptFileError: the model, its meta.json or its statistics are not readable; or a
            run folder without ``final/`` whose checkpoints are all damaged.
    """
    path = Path(path)
    if path.is_dir() and not (path / "model.zip").exists() and (path / KEPT).exists():
        path = path / KEPT
    if path.suffix == ".npz":
        return _kept(path, algo)
    if path.is_dir():
        candidates = [path / "model.zip", path / "final" / "model.zip"]
        path = next((c for c in candidates if c.exists()), None)
        if path is None:
            checkpoint = intact_checkpoint(Path(candidates[0].parent), using="loading")
            path = candidates[0] if checkpoint is None else checkpoint / "model.zip"
    if not path.exists():
        raise FileNotFoundError(f"no saved model at {path}")
    if not zipfile.is_zipfile(path):
        raise CorruptFileError(f"{path}: not a saved model (model.zip is a zip archive)", path)
    folder = path.parent
    meta = {}
    if (folder / "meta.json").exists():
        meta = read_checked(folder / "meta.json", lambda p: json.loads(p.read_text()), "JSON")
    algo = algo or meta.get("algo")
    if algo is None:
        raise TrainingError(f"{folder} has no meta.json: give the algorithm (--algo)")
    learner = algorithm_class(algo)
    model = read_checked(path, lambda p: learner.load(p, device=device), f"a saved {algo} model")
    vecnorm = None
    if (folder / "vecnormalize.pkl").exists():
        vecnorm = read_checked(folder / "vecnormalize.pkl", _unpickle, "VecNormalize statistics")
        vecnorm.training = False
    return SavedPolicy(model, algo, meta.get("env_id"), meta.get("env_kwargs") or {}, vecnorm)


def export_run(path: str | Path, out: str | Path) -> Path:
    """Keep the policy saved in `path` (as :func:`load_policy` finds it: a run folder, its
    ``final/`` or ``best/``, a ``model.zip``) in `out` (:func:`pliant.learn.kept.export_policy`),
    with its environment, and the run's configuration, seed and step where the run has them."""
    path = Path(path)
    saved = load_policy(path)
    if isinstance(saved.model, _NormalisedInput):
        raise PolicyError(f"{path} is a kept policy already: copy it")
    provenance: dict = {"env_id": saved.env_id, "env_kwargs": saved.env_kwargs}
    folder = path if path.is_dir() else path.parent
    for run in (folder, folder.parent):
        if (run / "config.yaml").is_file():
            config = read_checked(
                run / "config.yaml", lambda p: yaml.safe_load(p.read_text()), "YAML"
            )
            provenance.update(run=str(run), config=config, seed=(config or {}).get("seed"))
            break
    provenance["source"] = str(path)
    from pliant.learn import kept  # PyTorch, on first use

    return kept.export_policy(
        saved.model, out, algo=saved.algo, vecnormalize=saved.vecnormalize, provenance=provenance
    )


def _unpickle(path: Path):
    with open(path, "rb") as f:
        return pickle.load(f)


def evaluate_saved(
    path: str | Path,
    env_id: str | None = None,
    *,
    episodes: int = 10,
    env_kwargs: dict | None = None,
    algo: str | None = None,
    seed: int = 10_000,
    deterministic: bool = True,
    gif: Path | None = None,
    gif_episodes: int = 1,
    action_seed: int | None = None,
) -> Evaluation:
    """Evaluate a saved policy (``pliant eval``/``pliant enjoy``). The environment defaults to
    the one it was trained on, with the same keyword arguments. `action_seed`: torch seeded
    with it once the policy is loaded, so that sampled actions (``deterministic=False``) are
    the same draws from a saved model and from its kept actor (loading an SB3 model draws
    from torch's generator, loading a kept policy does not)."""
    saved = load_policy(path, algo)
    env_id = env_id or saved.env_id
    if env_id is None:
        raise ValueError("give the environment: the model's meta.json does not name it")
    kwargs = {**saved.env_kwargs, **(env_kwargs or {})}
    env = make_env(env_id, kwargs, render_mode="rgb_array" if gif else None)
    frames: list | None = [] if gif else None
    if action_seed is not None:
        import torch  # loaded with the policy already

        torch.manual_seed(action_seed)
    try:
        result = run_episodes(
            saved.model,
            env,
            episodes,
            normalize_obs=saved.normalize_obs,
            deterministic=deterministic,
            seed=seed,
            frames=frames,
            frame_episodes=gif_episodes,
        )
    finally:
        env.close()
    if gif and frames:
        save_frames(frames, gif, fps=env.metadata.get("render_fps", 10))
    return result


def save_frames(frames: list, path: Path, fps: int = 10) -> None:
    import imageio.v2 as imageio

    path.parent.mkdir(parents=True, exist_ok=True)
    imageio.mimsave(path, [np.asarray(f) for f in frames], duration=1000.0 / max(fps, 1), loop=0)


def latest_checkpoint(run_dir: Path) -> Path | None:
    found = _checkpoints(run_dir)
    return found[-1] if found else None


def _checkpoints(run_dir: Path) -> list[Path]:
    found = [p for p in (run_dir / "checkpoints").glob("step_*") if p.name[5:].isdigit()]
    return sorted(found, key=lambda p: int(p.name[5:]))


def check_checkpoint(folder: Path) -> None:
    """Raise a CorruptFileError naming the damaged file of a checkpoint: against its
    manifest, or, for a checkpoint written before manifests, by opening its files."""
    if check_manifest(folder):
        return

    def zip_archive(path: Path) -> None:
        with zipfile.ZipFile(path) as z:
            bad = z.testzip()
        if bad is not None:
            raise ValueError(f"its member {bad} is corrupt")

    def unpickle(path: Path) -> None:
        with open(path, "rb") as f:
            pickle.load(f)

    read_checked(folder / "model.zip", zip_archive, "a saved model (a zip archive)")
    read_checked(folder / "state.pkl", unpickle, "a checkpoint's state (a pickle)")
    if (folder / "vecnormalize.pkl").exists():
        read_checked(folder / "vecnormalize.pkl", unpickle, "VecNormalize statistics")
    if (folder / "replay_buffer.pkl").exists():  # off-policy algorithms
        read_checked(folder / "replay_buffer.pkl", unpickle, "a replay buffer (a pickle)")


def intact_checkpoint(run_dir: Path, using: str = "resuming from") -> Path | None:
    """The newest checkpoint of a run whose files are intact (None when it has none), with a
    CheckpointWarning naming each newer one skipped and the one used.

    Raises:
        CorruptFileError: the run has checkpoints, none of them intact (each one's damage
            named).
    """
    damaged = []
    for folder in reversed(_checkpoints(run_dir)):
        try:
            check_checkpoint(folder)
        except (CorruptFileError, FileNotFoundError) as exc:
            damaged.append(f"{folder.name}: {exc}")
            continue
        if damaged:
            warnings.warn(
                f"skipped damaged checkpoints ({'; '.join(damaged)}); {using} {folder}",
                CheckpointWarning,
                stacklevel=2,
            )
        return folder
    if damaged:
        raise CorruptFileError(
            f"no intact checkpoint in {run_dir / 'checkpoints'}: {'; '.join(damaged)}",
            run_dir / "checkpoints",
        )
    return None
