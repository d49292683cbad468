"""The Trunk proxy at coarser time steps (docs/proxy.md, "The proxy at its own time step"):
how well the calibrated proxy replays the FEM's pushes, and how fast, when its 0.3 s
environment step is taken in 30, 15 or 10 sub-steps (dt 0.01, 0.02, 0.03 s) while the FEM
keeps its 0.01 s.

The reference is the push calibration's (experiments/proxy/push_calibration.py: the FEM
Trunk's episodes by its five PPO policies and by random actions, recorded as the proxy's cable
actions with the FEM cube's track; made once into OUT/fem_pushes.npz, 43 episodes); the proxy
is a calibration report's ("parameters"), the optimisation / validation split the
calibration's (every other episode of each kind).

    python experiments/proxy/timestep.py [--calibration
        experiments/proxy/push_cocontraction/trunk-push_calibration.json] [--dt 0.01 0.02 0.03]

``--speed-only`` measures only the environments' speed (below) and adds it to the JSON.

Speed: environment steps per second of the FEM task (pliant/TrunkPush-v0) and the proxy's
(pliant/TrunkPushProxy-v0 with the calibration's proxy and the FEM's cable actions) at 0.01
and 0.03 s, random actions, blocks of 10 steps taken in turn from the four environments
(repeats), median per environment: the ratio of what PPO's 2.04e5 simulation steps cost on
each, measured side by side.

Writes experiments/results/proxy/timestep.json: per dt, the mean cube distance (mm) to the
FEM's over every step of each half and of the FEM policies' 20 episodes, the cubes' mean
travel, and the replay's wall time.

The control: the FEM itself at the coarser steps. The FEM policies' 20 episodes are run again
at 0.01 s (closed loop: the same episodes as the reference's, checked), and their commanded
actions replayed open loop on the FEM at each coarser dt (its cables still move at most 1 mm
a simulation step, SoftRobots' limit, so at 0.03 s they are three times slower): how far its
cube goes from the 0.01 s FEM's, beside the proxy's on the same episodes.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
import warnings
from pathlib import Path

import numpy as np

from pliant.envs.trunk_push import TrunkPushEnv
from pliant.learn.evaluate import load_policy
from pliant.proxy.calibrate import mean_distance
from pliant.transfer.fem_rl import FEM_KWARGS
from pliant.transfer.fem_rl import OUT as RUNS
from pliant.transfer.pushes import PUSH_POLICIES as POLICIES
from pliant.transfer.pushes import Pushes, cube_travel, proxy_pushes
from pliant.transfer.pushes import reference_pushes as reference
from pliant.transfer.rl import SETTINGS

OUT = Path("experiments/results/proxy/timestep.json")


def fem_coarse(fem: Pushes, dts: list[float], per_policy: int = 4) -> dict:
    """The FEM policies' episodes of the reference (policy k, episode e: goal seed
    3000 + 100 k + e) run again on the FEM at 0.01 s, their commanded actions replayed on the
    FEM at each of `dts`; the mean cube distance to the 0.01 s run and the wall times."""
    fine = TrunkPushEnv(**FEM_KWARGS)
    coarse = {
        dt: TrunkPushEnv(**{**FEM_KWARGS, "dt": dt, "substeps": int(round(0.3 / dt))}) for dt in dts
    }

    def run(env, choose, seed):
        obs, _ = env.reset(seed=seed)
        cubes, actions = [env.cube().copy()], []
        for k in range(fem.actions.shape[1]):
            actions.append(np.asarray(choose(obs, k), dtype=float))
            obs, *_ = env.step(actions[-1])
            cubes.append(env.cube().copy())
        return np.array(cubes), actions

    errors = {dt: [] for dt in dts}
    seconds = {dt: 0.0 for dt in [0.01, *dts]}
    rerun_gap = 0.0
    for k, name in enumerate(POLICIES):
        saved = load_policy(RUNS / name)
        index = np.flatnonzero(fem.kinds == name)
        for e in range(per_policy):

            def greedy(obs, _, saved=saved):
                return saved.model.predict(saved.normalize_obs(obs), deterministic=True)[0]

            clock = time.perf_counter()
            cubes, actions = run(fine, greedy, 3000 + 100 * k + e)
            seconds[0.01] += time.perf_counter() - clock
            rerun_gap = max(rerun_gap, float(np.abs(cubes - fem.cubes[index[e]]).max()))
            for dt, env in coarse.items():
                clock = time.perf_counter()
                replayed, _ = run(env, lambda obs, j, a=actions: a[j], 3000 + 100 * k + e)
                seconds[dt] += time.perf_counter() - clock
                errors[dt].append(float(np.linalg.norm(replayed - cubes, axis=1).mean()))
    return {
        "episodes": len(errors[dts[0]]),
        "rerun_vs_reference_max_mm": rerun_gap,
        "rows": [
            {
                "dt": dt,
                "cube_error_mm": float(np.mean(errors[dt])),
                "per_episode_mm": errors[dt],
                "replay_seconds": seconds[dt],
            }
            for dt in dts
        ],
        "fine_seconds": seconds[0.01],
    }


def speed(base: dict, repeats: int) -> dict:
    """Environment steps per second of the four environments (module docstring)."""
    from pliant.envs.trunk_push_proxy import TrunkPushProxyEnv

    envs = {
        f"{name}_dt{dt:g}": make(**{**kwargs, "dt": dt, "substeps": int(round(0.3 / dt))})
        for name, make, kwargs in (
            ("fem", TrunkPushEnv, FEM_KWARGS),
            ("proxy", TrunkPushProxyEnv, {**base, "actions": "cables"}),
        )
        for dt in (0.01, 0.03)
    }
    rates: dict = {name: [] for name in envs}
    rng = np.random.default_rng(0)
    for k in range(repeats):
        for name, env in envs.items():
            env.reset(seed=k)
            clock = time.perf_counter()
            for _ in range(10):
                env.step(rng.uniform(-1.0, 1.0, env.action_space.shape))
            rates[name].append(10 / (time.perf_counter() - clock))
    return {
        "repeats": repeats,
        "env_steps_per_second": {k: float(np.median(v)) for k, v in rates.items()},
        "all": rates,
    }


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument(
        "--calibration",
        type=Path,
        default=Path("experiments/proxy/push_cocontraction/trunk-push_calibration.json"),
    )
    parser.add_argument(
        "--reference", type=Path, default=Path("experiments/proxy/push/fem_pushes.npz")
    )
    parser.add_argument("--dt", type=float, nargs="+", default=[0.01, 0.02, 0.03])
    parser.add_argument("--out", type=Path, default=OUT)
    parser.add_argument("--speed-only", action="store_true")
    parser.add_argument("--repeats", type=int, default=5, help="of the speed measurement")
    args = parser.parse_args()
    warnings.simplefilter("ignore")
    if args.speed_only:
        report = json.loads(args.out.read_text())
        calibration = json.loads(Path(report["calibration"]).read_text())
        base = {**SETTINGS["trunk"]["env_kwargs"], **calibration["parameters"]}
        report["speed"] = speed(base, args.repeats)
        report["speed_command"] = "python experiments/proxy/timestep.py " + " ".join(sys.argv[1:])
        args.out.write_text(json.dumps(report, indent=1))
        print(json.dumps(report["speed"]["env_steps_per_second"]))
        return
    if args.reference.exists():
        fem = Pushes.load(args.reference)
    else:  # the push calibrations' reference: 4 episodes a FEM policy, 12 random of each std
        fem = reference(per_policy=4, random_episodes=12, moved=2.0)
        args.reference.parent.mkdir(parents=True, exist_ok=True)
        fem.save(args.reference)
    order = np.concatenate([np.flatnonzero(fem.kinds == k) for k in dict.fromkeys(fem.kinds)])
    fem = Pushes(fem.actions[order], fem.cubes[order], fem.kinds[order])
    calibration = json.loads(args.calibration.read_text())
    base = {**SETTINGS["trunk"]["env_kwargs"], **calibration["parameters"]}
    optimise, validate = np.arange(0, len(fem.kinds), 2), np.arange(1, len(fem.kinds), 2)
    policies = np.flatnonzero(np.isin(fem.kinds, POLICIES))
    rows = []
    for dt in args.dt:
        substeps = int(round(0.3 / dt))
        clock = time.perf_counter()
        cubes = proxy_pushes(fem, {**base, "dt": dt, "substeps": substeps})
        rows.append(
            {
                "dt": dt,
                "substeps": substeps,
                "optimisation_error_mm": mean_distance(fem.cubes[optimise], cubes[optimise]),
                "validation_error_mm": mean_distance(fem.cubes[validate], cubes[validate]),
                "policy_episodes_error_mm": float(
                    np.linalg.norm(cubes[policies] - fem.cubes[policies], axis=-1).mean()
                ),
                "proxy_travel_mm": float(cube_travel(cubes).mean()),
                "replay_seconds": time.perf_counter() - clock,
            }
        )
        print(json.dumps(rows[-1]), flush=True)
    report = {
        "command": "python experiments/proxy/timestep.py " + " ".join(sys.argv[1:]),
        "calibration": str(args.calibration),
        "reference": str(args.reference),
        "episodes": len(fem.kinds),
        "fem_travel_mm": float(cube_travel(fem.cubes).mean()),
        "rows": rows,
        "fem_at_coarser_steps": fem_coarse(fem, [dt for dt in args.dt if dt > 0.01]),
    }
    print(json.dumps({k: v for k, v in report["fem_at_coarser_steps"].items() if k != "rows"}))
    for row in report["fem_at_coarser_steps"]["rows"]:
        print({k: v for k, v in row.items() if k != "per_episode_mm"})
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(report, indent=1))


if __name__ == "__main__":
    main()
