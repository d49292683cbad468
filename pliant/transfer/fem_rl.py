"""The proxy pipeline against RL directly on the FEM, thesis §4.1.3 (Trunk pushing a cube: the
proxy method ends 2 mm from the goal, PPO on the FEM with the same budget 4.5 mm): the FEM
environment's settings, PPO on the FEM with the proxy's settings, the evaluation goals, and a
proxy policy's transfer to the FEM by `pliant proxy transfer`'s loop (experiments/proxy/
vs_fem_rl.py and the studies that build on it).

Each FEM episode is run as the environment runs it: 10 steps of 0.3 s, ended at the first step
that leaves the cube within 8 mm of the goal (the same for both methods), on the same 20 goals
(the environments' seeds 1000-1019, which draw the same goal offsets in both).
"""

from __future__ import annotations

import dataclasses
import json
import time
from pathlib import Path

import numpy as np

from pliant.envs.trunk_push_proxy import TrunkPushProxyEnv
from pliant.errors import TrainingError
from pliant.learn.evaluate import load_policy
from pliant.learn.training import train
from pliant.learn.vec import make_env
from pliant.transfer.proxy import TRUNK_GAINS, trunk_transfer
from pliant.transfer.rl import RUNS, episode, rl_config

FEM_ENV = "pliant/TrunkPush-v0"
FEM_KWARGS = {
    "substeps": 30,
    "settle_steps": 30,
    "max_long_displacement": 14.0,
    "max_short_displacement": 8.0,
}
GOALS = range(1000, 1020)
OUT = Path("experiments/results/proxy/fem_vs_proxy")
"""The comparison's results (relative to the working directory)."""


def suffix(algo: str, seed: int, planar: bool = False) -> str:
    """What names a run other than PPO's of seed 0 on all cables: "_sac", "_seed1",
    "_sac_seed1", "_planar_seed1"."""
    name = "" if algo == "PPO" else f"_{algo.lower()}"
    return name + ("_planar" if planar else "") + ("" if seed == 0 else f"_seed{seed}")


def fem_kwargs(planar: bool, dt: float | None = None, cable_step: float | None = None) -> dict:
    """The FEM environment's keywords; `planar`: only the -x/+x cables driven; `dt`: the FEM
    stepped coarser, its 0.3 s environment step in as many sub-steps of `dt`; `cable_step`:
    the most a cable's displacement may change in one simulation step, mm (SoftRobots'
    maxDispVariation, the Trunk's 1 mm by default; 1 mm a step of 0.03 s is a third of the
    cable speed at 0.01 s). `dt` and `cable_step` are for training only: every policy is
    evaluated on the FEM at its own 0.01 s and 1 mm."""
    kwargs = {**FEM_KWARGS, "planar": True} if planar else dict(FEM_KWARGS)
    if cable_step is not None:
        if not (np.isfinite(cable_step) and cable_step > 0):
            raise TrainingError(f"the FEM's cable step must be > 0 mm, got {cable_step}")
        kwargs["max_displacement_change"] = float(cable_step)
    if dt is not None:
        substeps = int(round(0.3 / dt))
        if abs(substeps * dt - 0.3) > 1e-9:
            raise TrainingError(f"the FEM's dt {dt} s does not divide the 0.3 s environment step")
        kwargs.update(dt=dt, substeps=substeps)
    return kwargs


def train_on_fem(
    env_steps: int,
    seed: int,
    resume: bool,
    algo: str,
    planar: bool = False,
    hyperparams: dict | None = None,
    tag: str = "",
    dt: float | None = None,
    cable_step: float | None = None,
    runs: Path = RUNS,
) -> tuple[Path, dict]:
    """`algo` with the proxy's Trunk settings (:func:`pliant.transfer.rl.rl_config`) directly
    on the FEM (:func:`fem_kwargs`); the run folder under `runs` and the training summary."""
    run_dir = Path(runs) / ("proxy_vs_fem_rl" + tag + suffix(algo, seed, planar))
    kwargs = fem_kwargs(planar, dt, cable_step)
    config = rl_config("trunk", FEM_ENV, kwargs, env_steps, seed, algo, hyperparams)
    result = train(None if resume else config, run_dir, resume=resume)
    return run_dir, result.summary


def evaluate_on_fem(policy_dir: Path, planar: bool = False) -> list[dict]:
    """The saved policy's greedy episodes on the FEM, one a goal of :data:`GOALS`."""
    saved = load_policy(policy_dir)
    env = make_env(FEM_ENV, fem_kwargs(planar))

    def greedy(obs, k):
        return saved.model.predict(saved.normalize_obs(obs), deterministic=True)[0]

    return [episode(env, greedy, s) for s in GOALS]


def transfer_episode(saved, offset_xz, gains, tolerance: float = 8.0, seed: int = 0) -> dict:
    """The loaded proxy policy `saved` (load_policy) through `pliant proxy transfer`'s loop
    on the FEM for the goal at the cube's start plus `offset_xz`: the FEM's episode as the
    environment runs it (the direct RL's evaluation too), 10 steps ended at the first that
    leaves the FEM's cube within `tolerance` mm of the goal; `seed` labels the row (the goal's
    draw)."""
    normalize = saved.normalize_obs or (lambda obs: obs)
    loop = trunk_transfer(gains=gains, goal_offset=tuple(offset_xz), env_kwargs=saved.env_kwargs)

    def chooser(obs):
        return saved.model.predict(normalize(obs), deterministic=True)[0]

    clock = time.perf_counter()
    goal = loop.env.task["goal"]

    def distance(cube: np.ndarray) -> float:
        return float(np.hypot(*(cube - goal)[[0, 2]]))

    def within() -> bool:
        return distance(loop.state.rigid_positions[0]) < tolerance

    loop.run(policy=chooser, steps=10, until=within)
    return {
        "seed": seed,
        "goal_offset_xz": [float(offset_xz[0]), float(offset_xz[1])],
        "steps": len(loop.result.steps),
        "fem_distance": distance(loop.state.rigid_positions[0]),
        "proxy_distance": distance(loop.env.state.rigid_positions[0]),
        "relative_reward_difference": loop.result.relative_difference,
        "wall_s": time.perf_counter() - clock,
    }


def transfer_proxy_policy(
    policy_dir: Path, time_register: int | None = None, rest_offset: bool = False
) -> list[dict]:
    """The proxy policy's episode on the FEM for each goal; `time_register`: proxy steps
    between realignments (the FEM's cube imposed on the proxy, the policy re-planning from
    there), None for the thesis' 10 (none within the 10 steps: the thesis' realignment is
    not due within an episode); `rest_offset`: the gains' (the FEM follows the proxy's
    displacements from its own settled shape)."""
    saved = load_policy(policy_dir)  # its algorithm from its meta.json
    probe = TrunkPushProxyEnv(**saved.env_kwargs)
    gains = dataclasses.replace(TRUNK_GAINS, rest_offset=rest_offset)
    if time_register is not None:
        gains = dataclasses.replace(gains, time_register=time_register)
    rows = []
    for seed in GOALS:
        probe.reset(seed=seed)
        offset = probe.task["goal"] - probe.cube()
        rows.append(transfer_episode(saved, (offset[0], offset[2]), gains, seed=seed))
        print(json.dumps(rows[-1]), flush=True)
    return rows


def summary(distances: list[float]) -> dict:
    """The final cube-goal distances' mean and median, and the share under 8 mm."""
    if len(distances) == 0:
        raise TrainingError("no final distances to summarise")
    d = np.asarray(distances)
    return {
        "mean_final_distance_mm": float(d.mean()),
        "median_final_distance_mm": float(np.median(d)),
        "solved_under_8mm": float(np.mean(d < 8.0)),
    }


#: The fixed-goal study's goals (experiments/proxy/fixed_goal.py): name -> the goal's offset
#: (x, z) from the cube's start, mm.
FIXED_GOALS = {"x25": (25.0, 0.0), "x30z-15": (30.0, -15.0), "x20z12": (20.0, 12.0)}
FIXED_GOAL_TOLERANCE = 5.0  # mm, the thesis' stop (Fig. 4.6)
FIXED_GOAL_OUT = Path("experiments/results/proxy/fixed_goal")
"""The fixed-goal study's results (relative to the working directory)."""


def goal_kwargs(offset: tuple[float, float]) -> dict:
    """The environments' keywords that fix the goal at `offset` (x, z) from the cube's start,
    solved within :data:`FIXED_GOAL_TOLERANCE`."""
    return {"goal_low": offset, "goal_high": offset, "goal_tolerance": FIXED_GOAL_TOLERANCE}
