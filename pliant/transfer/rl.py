"""PPO (or SAC) on the beam-skeleton proxies, thesis §4.1.3 ("the PPO algorithm determines a
strategy on the proxy that solves the task", about 2e4 simulation steps for the Multigait, 2e5
for the Trunk), with Pliant's training stack: the settings the proxy studies share
(experiments/proxy/), one episode's summary, the greedy policy's evaluation beside the
baselines, the degraded proxies' parameters, and a whole training run with its report.

Multigait (pliant/MultigaitProxy-v0, 12 steps of 0.6 s, Discrete(6)): the greedy policy's
forward travel over an episode beside the hand gait's (rear, centre, front inflated, then
deflated in that order) and random actions'. Trunk (pliant/TrunkPushProxy-v0, 10 steps of
0.3 s, Box(5), goal drawn in (x, z)): on 20 fixed goals, the final cube-goal distance and the
share solved (< 8 mm) beside doing nothing and random actions.
"""

from __future__ import annotations

import json
import shutil
import warnings
from pathlib import Path

import numpy as np
import torch

from pliant.errors import TrainingError
from pliant.files import write_results
from pliant.learn.config import TrainConfig, deep_merge
from pliant.learn.evaluate import KEPT, export_run, load_policy
from pliant.learn.training import train
from pliant.learn.vec import make_env
from pliant.proxy.builders import MULTIGAIT_PARAMETERS, TRUNK_PARAMETERS
from pliant.proxy.calibrate import fitted_proxy

RUNS = Path("runs")
"""Where training runs keep their checkpoints (relative to the working directory)."""
RESULTS = Path("experiments/results/proxy")
"""Where the proxy studies' policies and reports go (relative to the working directory)."""

#: the Multigait's hand gait (Discrete(6): 2 g inflates group g of centre, front, rear; 2 g + 1
#: deflates it), twice over the 12-step episode.
HAND_GAIT = [4, 0, 2, 5, 1, 3] * 2

SETTINGS = {
    "multigait": {
        "env_id": "pliant/MultigaitProxy-v0",
        "env_kwargs": {"observe_commands": True},
        "normalize": {"norm_obs": True, "norm_reward": False},
        "hyperparams": {
            "policy": "MlpPolicy",
            "n_steps": 120,
            "batch_size": 60,
            "gamma": 0.95,
            "ent_coef": 0.01,
            "learning_rate": 1e-3,
            "policy_kwargs": {"net_arch": [64, 64]},
        },
        "eval_freq": 240,
        "eval_episodes": 1,
        "env_steps": 3000,
    },
    "trunk": {
        "env_id": "pliant/TrunkPushProxy-v0",
        "env_kwargs": {"bend_limit": 0.2},
        "normalize": {"norm_obs": True, "norm_reward": True},
        "hyperparams": {
            "policy": "MlpPolicy",
            "n_steps": 200,
            "batch_size": 50,
            "gamma": 0.95,
            "ent_coef": 0.0,
            "learning_rate": 3e-4,
            "policy_kwargs": {"net_arch": [128, 128]},
        },
        "eval_freq": 1000,
        "eval_episodes": 10,
        "env_steps": 6700,
    },
}

#: SAC beside the thesis' PPO (``--algo SAC``, a departure: the thesis used PPO through
#: SofaGym): the Trunk's continuous bendings with off-policy updates, one gradient step an
#: environment step, observations normalised (SAC's entropy term sets the reward's scale).
SAC_SETTINGS = {
    "trunk": {
        "normalize": {"norm_obs": True, "norm_reward": False},
        "hyperparams": {
            "policy": "MlpPolicy",
            "learning_starts": 500,
            "batch_size": 256,
            "buffer_size": 100_000,
            "gamma": 0.95,
            "learning_rate": 3e-4,
            "policy_kwargs": {"net_arch": [256, 256]},
        },
    },
}


def settings(robot: str, algo: str = "PPO") -> dict:
    """ROBOT's settings for `algo` (PPO, or SAC where :data:`SAC_SETTINGS` has ROBOT)."""
    if robot not in SETTINGS:
        raise TrainingError(f"no proxy RL settings for robot {robot!r}: one of {sorted(SETTINGS)}")
    if algo == "PPO":
        return SETTINGS[robot]
    if algo == "SAC" and robot in SAC_SETTINGS:
        return {**SETTINGS[robot], **SAC_SETTINGS[robot]}
    raise TrainingError(f"no {algo} settings for the {robot} proxy (PPO; SAC for the Trunk)")


def episode(env, choose, seed: int, options: dict | None = None) -> dict:
    """One episode; `choose(obs, k)` gives the k-th action."""
    obs, _ = env.reset(seed=seed, options=options)
    total, k, info = 0.0, 0, {}
    while True:
        obs, reward, terminated, truncated, info = env.step(choose(obs, k))
        total, k = total + reward, k + 1
        if terminated or truncated:
            break
    base = env.unwrapped
    out = {"return": total, "length": k}
    if hasattr(base, "distance"):
        out.update(distance=base.distance(), solved=bool(terminated))
    else:
        out["travel_mm"] = info["travelled"]
    return out


def evaluate(robot: str, policy_dir: Path, env_kwargs: dict, seed: int) -> dict:
    """The greedy learned policy beside the baselines (module docstring)."""
    saved = load_policy(policy_dir)
    env = make_env(settings(robot)["env_id"], env_kwargs)
    env.action_space.seed(seed)
    actions: list = []

    def greedy(obs, k):
        action = saved.model.predict(saved.normalize_obs(obs), deterministic=True)[0]
        actions.append(action.tolist())
        return action

    def random(obs, k):
        return env.action_space.sample()

    if robot == "multigait":
        return {
            "learned": episode(env, greedy, 0),
            "learned_actions": actions,
            "hand_gait": episode(env, lambda obs, k: HAND_GAIT[k], 0),
            "random_mean_of_5_travel_mm": float(
                np.mean([episode(env, random, s)["travel_mm"] for s in range(5)])
            ),
        }
    still = np.zeros(env.action_space.shape)
    goals = range(1000, 1020)
    out = {}
    for name, choose in (("learned", greedy), ("still", lambda o, k: still), ("random", random)):
        rows = [episode(env, choose, s) for s in goals]
        if name == "learned":
            out["learned_actions_first_goal"] = actions[: rows[0]["length"]]
        out[name] = {
            "mean_final_distance_mm": float(np.mean([r["distance"] for r in rows])),
            "solved": float(np.mean([r["solved"] for r in rows])),
            "mean_return": float(np.mean([r["return"] for r in rows])),
        }
    return out


def degraded(robot: str, level: float, seed: int, reference: dict | None = None) -> dict:
    """The calibrated proxy's parameters p (the builder's defaults, or `reference`) turned
    into p (1 + level U(-1, 1)) (thesis §4.1.3's degraded proxies; the authors' noise): the
    proxy builder's keywords."""
    settings(robot)
    if reference is None:
        reference = MULTIGAIT_PARAMETERS if robot == "multigait" else TRUNK_PARAMETERS
    rng = np.random.default_rng(seed)
    return {k: float(v * (1.0 + level * rng.uniform(-1.0, 1.0))) for k, v in reference.items()}


def rl_config(
    robot: str,
    env_id: str,
    env_kwargs: dict,
    steps: int,
    seed: int,
    algo: str = "PPO",
    hyperparams: dict | None = None,
) -> TrainConfig:
    """`algo` (PPO, or SAC where :data:`SAC_SETTINGS` has ROBOT) with ROBOT's settings (one
    environment in the process) on `env_id`; `hyperparams` replace the settings' own
    (SB3's keywords; ``policy_kwargs`` merged key by key)."""
    s = settings(robot, algo)
    if hyperparams:
        s = {**s, "hyperparams": deep_merge(s["hyperparams"], hyperparams)}
    return TrainConfig(
        env_id=env_id,
        algo=algo,
        total_timesteps=steps,
        seed=seed,
        env_kwargs=env_kwargs,
        n_envs=1,
        vec_env="dummy",
        normalize=dict(s["normalize"]),
        eval_freq=s["eval_freq"],
        eval_episodes=s["eval_episodes"],
        checkpoint_freq=s["eval_freq"],
        video_episodes=0,
        hyperparams=s["hyperparams"],
    )


def learn(
    robot: str,
    *,
    env_steps: int | None = None,
    seed: int = 0,
    points_only: bool = False,
    noise: float = 0.0,
    bend_limit: float | None = None,
    tag: str = "",
    resume: bool = False,
    command: str = "",
    parameters: Path | None = None,
    contact: str | None = None,
    algo: str = "PPO",
    planar: bool = False,
    hyperparams: dict | None = None,
    cables: bool = False,
    dt: float | None = None,
    runs: Path = RUNS,
    results: Path = RESULTS,
) -> dict:
    """Train `algo` on ROBOT's proxy (its parameters degraded by `noise`), evaluate the final
    policy, and write the results folder ``results/rl_ROBOTTAG`` (the policy, report.json,
    learning_curve.png; training checkpoints in ``runs/proxy_rl_ROBOTTAG``); the report.
    `dt`: the proxy's time step, its environment's step (0.3 s the Trunk's, 0.6 the
    Multigait's) kept in as many sub-steps."""
    s = settings(robot, algo)
    warnings.simplefilter("ignore")
    torch.set_num_threads(1)
    env_kwargs = dict(s["env_kwargs"])
    if points_only:
        env_kwargs.pop("observe_commands", None)
    fitted = None
    if parameters is not None:  # a calibration report's fitted parameters
        fitted = json.loads(Path(parameters).read_text())
        env_kwargs.update(fitted_proxy(fitted))  # the proxy it was fitted as (and its contact)
    if noise > 0.0:  # the draw `seed` around the defaults or the fitted parameters
        env_kwargs.update(degraded(robot, noise, seed, fitted and fitted["parameters"]))
    if bend_limit is not None:
        env_kwargs["bend_limit"] = bend_limit
    if contact is not None:  # how the proxy touches: "nodes" or "surface" (skinned FEM surface)
        env_kwargs["contact"] = contact
    if planar:  # the Trunk's beams bend towards +-x only (TrunkPushProxyEnv's `planar`)
        env_kwargs["planar"] = True
    if cables:  # the FEM Trunk's action space, mapped to the bendings
        env_kwargs["actions"] = "cables"
    if dt is not None:  # a coarser (or finer) proxy step, the environment's step unchanged
        probe = make_env(s["env_id"], env_kwargs).unwrapped
        duration = probe.dt * probe.substeps
        substeps = int(round(duration / dt))
        if substeps < 1 or abs(substeps * dt - duration) > 1e-9:
            raise TrainingError(f"dt {dt} s does not divide the environment's step, {duration} s")
        env_kwargs.update(dt=dt, substeps=substeps)
    name = f"rl_{robot}{tag}"
    run_dir = Path(runs) / f"proxy_{name}"
    out = Path(results) / name
    steps = env_steps or s["env_steps"]
    config = rl_config(robot, s["env_id"], env_kwargs, steps, seed, algo, hyperparams)
    result = train(None if resume else config, run_dir, resume=resume)
    substeps = make_env(s["env_id"], env_kwargs).unwrapped.substeps
    report = {
        "robot": robot,
        "command": command,
        "env_id": s["env_id"],
        "env_kwargs": env_kwargs,
        "proxy_noise": noise,
        "env_steps": result.summary["steps"],
        "simulation_steps": result.summary["steps"] * substeps,
        "training_seconds": result.summary["wall_seconds"],
        "algo": algo,
        "hyperparams": config.hyperparams,
        "normalize": config.normalize,
        "seed": seed,
        "evaluation": evaluate(robot, run_dir / "final", env_kwargs, seed),
        "curve": json.loads((run_dir / "evaluations.json").read_text()),
    }
    out.mkdir(parents=True, exist_ok=True)
    # the kept policy: what acting needs (pliant.learn.kept), not the run's model.zip
    export_run(run_dir / "final", out / KEPT)
    shutil.copy(run_dir / "learning_curve.png", out / "learning_curve.png")
    write_results(out / "report.json", report)
    return report
