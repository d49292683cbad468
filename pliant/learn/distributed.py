"""Scale-out on Ray (optional extra ``pliant[ray]``): environment workers as Ray actors behind
SB3's VecEnv interface, and Ray Tune sweeps whose trials are ordinary training runs.

One training run, its environments on a cluster::

    ray start --head                       # on the head machine
    ray start --address HEAD:6379          # on every other machine
    pliant train pliant/Trunk-v0 --algo PPO --n-envs 32 --ray auto   # on the head

The learner (SB3, one process) stays where ``pliant train`` runs; each environment is an actor
placed by Ray on any machine of the cluster with a free CPU; actions and observations travel
through Ray's object store at each step, so this pays when an environment step costs much more
than a round trip (tens of milliseconds and up: Pliant's FEM environments).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from stable_baselines3.common.vec_env import VecEnv
from stable_baselines3.common.vec_env.subproc_vec_env import _stack_obs

from pliant.errors import MissingDependencyError, WorkerError
from pliant.learn.config import _read_yaml
from pliant.processes import ProcessIdentity, driver_identity, exit_with_process


def require_ray():
    try:
        import ray
    except ImportError as exc:  # pragma: no cover - depends on the installation
        raise MissingDependencyError(
            "Ray is not installed: pip install 'pliant[ray]' (or 'ray[tune]')"
        ) from exc
    return ray


class EnvWorker:
    """One environment and SB3's worker protocol (auto-reset, terminal observation), as a Ray
    actor (``ray.remote(EnvWorker)``).

    driver: the process that drives it (:func:`pliant.processes.driver_identity`); on the same
    machine, the actor ends within half a second of its death (before the environment is
    built: meshing can take a while).
    """

    def __init__(
        self, factory: Callable[[], gym.Env], driver: ProcessIdentity | None = None
    ) -> None:
        if driver is not None:
            exit_with_process(driver)
        self.env = factory()

    def spaces(self):
        return self.env.observation_space, self.env.action_space

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        done = terminated or truncated
        info["TimeLimit.truncated"] = truncated and not terminated
        reset_info = {}
        if done:
            info["terminal_observation"] = obs
            obs, reset_info = self.env.reset()
        return obs, reward, done, info, reset_info

    def reset(self, seed, options):
        return self.env.reset(seed=seed, **({"options": options} if options else {}))

    def render(self):
        return self.env.render()

    def call(self, name: str, args, kwargs):
        return self.env.get_wrapper_attr(name)(*args, **kwargs)

    def get_attr(self, name: str):
        return self.env.get_wrapper_attr(name)

    def set_attr(self, name: str, value) -> None:
        setattr(self.env, name, value)

    def is_wrapped(self, wrapper_class) -> bool:
        from stable_baselines3.common.env_util import is_wrapped

        return is_wrapped(self.env, wrapper_class)

    def close(self) -> None:
        self.env.close()


class RayVecEnv(VecEnv):
    """n environments, each in a Ray actor (one CPU each by default).

    address: "auto" (join the running cluster), "local" or None (start Ray in this process if
    it is not running), or a cluster address ("ray://HEAD:10001", "HEAD:6379").
    """

    def __init__(
        self,
        env_fns: Sequence[Callable[[], gym.Env]],
        address: str | None = None,
        num_cpus_per_env: float = 1.0,
    ) -> None:
        ray = require_ray()
        if not ray.is_initialized():
            if address in (None, "local"):
                ray.init(include_dashboard=False, log_to_driver=False)
            else:
                ray.init(address=address, include_dashboard=False, log_to_driver=False)
        self._ray = ray
        actor = ray.remote(num_cpus=num_cpus_per_env)(EnvWorker)
        driver = driver_identity()
        self.workers = [actor.remote(fn, driver) for fn in env_fns]
        observation_space, action_space = self._get(self.workers[0].spaces.remote())
        super().__init__(len(env_fns), observation_space, action_space)
        self._pending = None

    def _get(self, refs):
        """``ray.get(refs)``; an actor that died (killed, out of memory, its node lost) stops
        the run with a WorkerError giving Ray's cause, never a hang."""
        try:
            return self._ray.get(refs)
        except self._ray.exceptions.RayActorError as exc:
            cause = next((line for line in str(exc).splitlines() if line.strip()), "")
            raise WorkerError(f"an environment worker (a Ray actor) died: {cause.strip()}") from exc

    def _indices(self, indices) -> list[int]:
        if indices is None:
            return list(range(self.num_envs))
        return [indices] if isinstance(indices, int) else list(indices)

    def step_async(self, actions: np.ndarray) -> None:
        self._pending = [w.step.remote(a) for w, a in zip(self.workers, actions, strict=True)]

    def step_wait(self):
        results = self._get(self._pending)
        self._pending = None
        obs, rewards, dones, infos, self.reset_infos = zip(*results, strict=True)
        return _stack_obs(obs, self.observation_space), np.stack(rewards), np.stack(dones), infos

    def reset(self):
        results = self._get(
            [w.reset.remote(self._seeds[i], self._options[i]) for i, w in enumerate(self.workers)]
        )
        obs, self.reset_infos = zip(*results, strict=True)
        self._reset_seeds()
        self._reset_options()
        return _stack_obs(obs, self.observation_space)

    def close(self) -> None:
        for w in self.workers:
            self._ray.kill(w)
        self.workers = []

    def get_images(self):
        return self._get([w.render.remote() for w in self.workers])

    def get_attr(self, attr_name: str, indices=None) -> list[Any]:
        return self._get(
            [self.workers[i].get_attr.remote(attr_name) for i in self._indices(indices)]
        )

    def set_attr(self, attr_name: str, value, indices=None) -> None:
        self._get(
            [self.workers[i].set_attr.remote(attr_name, value) for i in self._indices(indices)]
        )

    def env_method(self, method_name: str, *args, indices=None, **kwargs) -> list[Any]:
        return self._get(
            [self.workers[i].call.remote(method_name, args, kwargs) for i in self._indices(indices)]
        )

    def env_is_wrapped(self, wrapper_class, indices=None) -> list[bool]:
        return self._get(
            [self.workers[i].is_wrapped.remote(wrapper_class) for i in self._indices(indices)]
        )


def _sample(spec):
    """A Tune search space from YAML: ``{grid: [...]}``, ``{choice: [...]}``,
    ``{uniform: [a, b]}``, ``{loguniform: [a, b]}``, ``{randint: [a, b]}``, or a constant."""
    from ray import tune

    if isinstance(spec, dict) and len(spec) == 1:
        ((kind, values),) = spec.items()
        if kind == "grid":
            return tune.grid_search(list(values))
        if kind in ("choice", "uniform", "loguniform", "randint", "quniform"):
            return getattr(tune, kind)(*values) if kind != "choice" else tune.choice(values)
    if isinstance(spec, dict):
        return {k: _sample(v) for k, v in spec.items()}
    return spec


def _set_dotted(config: dict, dotted: str, value) -> None:
    keys = dotted.split(".")
    for key in keys[:-1]:
        config = config.setdefault(key, {})
    config[keys[-1]] = value


def tune_sweep(
    env_id: str,
    sweep_file: str | Path,
    *,
    algo: str | None = None,
    out: str | Path = "runs/tune",
    address: str | None = None,
    num_samples: int | None = None,
    cpus_per_trial: float = 1.0,
) -> list[dict]:
    """``pliant tune``: a Ray Tune sweep; each trial is a normal training run (its own folder
    with checkpoints, TensorBoard logs and evaluations) and reports its final evaluation.

    The sweep file::

        algo: PPO
        base: {total_timesteps: 20000, n_envs: 1}     # TrainConfig fields for every trial
        num_samples: 1                                # trials per grid point
        metric: success_rate                          # or mean_return
        search:                                       # dotted TrainConfig fields
          seed: {grid: [0, 1, 2]}
          hyperparams.learning_rate: {loguniform: [1.0e-4, 1.0e-3]}
    """
    sweep = _read_yaml(Path(sweep_file), what="a sweep (YAML)")
    ray = require_ray()
    from ray import tune

    algo = algo or sweep.get("algo", "PPO")
    base = sweep.get("base") or {}
    metric = sweep.get("metric", "success_rate")
    out = Path(out).absolute()
    space = {key: _sample(spec) for key, spec in (sweep.get("search") or {}).items()}
    samples = num_samples or sweep.get("num_samples", 1)
    driver = driver_identity()

    def trial(params: dict) -> None:
        import copy

        from pliant.learn.config import load_config
        from pliant.learn.training import train

        exit_with_process(driver)  # a trial on this machine ends with the sweep's driver

        overrides = copy.deepcopy(base)
        for key, value in params.items():
            _set_dotted(overrides, key, value)
        # Tune gives the trial its CPUs; stepping in the trial's process avoids a second pool.
        overrides.setdefault("vec_env", "dummy")
        config = load_config(env_id, algo, overrides=overrides)
        name = "_".join(
            f"{k.split('.')[-1]}={v:.4g}" if isinstance(v, float) else f"{k.split('.')[-1]}={v}"
            for k, v in sorted(params.items())
        )
        if samples > 1:  # repeated grid points: the trial's id tells them apart
            name = f"{name}_{tune.get_context().get_trial_id()}"
        result = train(config, out / (name or "trial"))
        final = result.summary["final_evaluation"] or {}
        score = final.get("success_rate")
        tune.report(
            {
                "success_rate": -1.0 if score is None else score,
                "mean_return": final.get("mean_return", float("nan")),
                "steps": result.summary["steps"],
            }
        )

    if not ray.is_initialized():
        ray.init(address=address, include_dashboard=False, log_to_driver=False)
    tuner = tune.Tuner(
        tune.with_resources(trial, {"cpu": cpus_per_trial}),
        param_space=space,
        tune_config=tune.TuneConfig(num_samples=samples, metric=metric, mode="max"),
        run_config=tune.RunConfig(storage_path=str(out / "ray"), name="sweep"),
    )
    results = tuner.fit()
    rows = []
    for r in results:
        rows.append(
            {
                "config": r.config,
                **{k: r.metrics.get(k) for k in ("success_rate", "mean_return", "steps")},
            }
        )
    return rows
