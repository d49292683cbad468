"""TrunkSpaceDebris: how often does the whole-arm pull catch? (issue #16; the expert that
``trunk_debris_ppo.py --bc`` clones.)

    PYTHONPATH=. python experiments/rl/trunk_debris_pull.py [--tests 100]

Plays ``pliant.envs.trunk_space_debris:expert`` (the long cables facing the cube pulled 2 mm a
step to the end of their course and held) on the test episodes of trunk_debris_ppo.py (seeds
30000 on) of each setting below, scored by the catch test (``success="catch"``: opposite faces
pressed, the cube off the hull, the last 5 steps), and records per episode the cube's size and
placement (height of its centre, distance from the trunk's axis, azimuth), the catch, and
the default test (two faces at the last step). The setting ``catchable_rates`` is a planning
expert: on each placement the pull at the full rate, then at 3/4 and 1/2 of it until one
catches (``rate`` in its records). Writes
experiments/results/rl/trunk_debris_pull/summary.json (one file, rewritten atomically after
each setting; a rerun skips the settings done).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from experiments.rl.trunk_debris_ppo import VARIANTS
from pliant.envs import make
from pliant.envs.trunk_space_debris import expert, sized_expert
from pliant.files import write_json

RESULTS = Path("experiments/results/rl/trunk_debris_pull")
CATCHABLE = VARIANTS["catchable"]  # where the planner found catches
# name: (environment keywords, the pull's rates tried in turn on each placement; "sized": the
# rate sized_expert chooses from the cube's size, one try)
SETTINGS = {
    "catchable": (CATCHABLE, (1.0,)),
    # the same, turned about the trunk as the environment's default draws (+-30 deg)
    "catchable_azimuth30": ({**CATCHABLE, "azimuth_range": float(np.radians(30.0))}, (1.0,)),
    # the environment's defaults: cubes of 20-40 mm at z 110-160, gap 5-20, +-30 deg
    "default": ({}, (1.0,)),
    # a planning expert: the full rate, or if it does not catch, 3/4 of it, or half
    "catchable_rates": (CATCHABLE, (1.0, 0.75, 0.5)),
    # the rate chosen by the cube's size (full for 40 mm, half for 35), what --bc-expert
    # sized_expert of trunk_debris_ppo.py clones
    "catchable_sized": (CATCHABLE, ("sized",)),
    # the long cables' course 40 mm instead of 35 (session 39)
    "catchable_course40": (VARIANTS["catchable_course40"], (1.0,)),
    "catchable_course40_azimuth30": (
        {**VARIANTS["catchable_course40"], "azimuth_range": float(np.radians(30.0))},
        (1.0,),
    ),
}


def episode(env, act, obs) -> dict:
    """Play `act` (observation -> action) from `obs` to the episode's end; how it ended (a
    diverged episode's info has no verdict: no catch)."""
    for _ in range(env.unwrapped.horizon):
        obs, _, terminated, truncated, info = env.step(act(obs))
        if terminated or truncated:
            break
    return {
        "catch": bool(info.get("is_success", False)),
        "held": int(info.get("held", 0)),
        "faces_at_end": int(info.get("faces", 0)),
        "lost": bool(terminated and not truncated),
        "diverged": "diverged" in info,
    }


def play(env_kwargs: dict, tests: int, rates: tuple) -> list[dict]:
    env = make("pliant/TrunkSpaceDebris-v0", **env_kwargs)
    records = []
    for k in range(tests):
        for rate in rates:  # the first that catches
            obs, _ = env.reset(seed=30_000 + k)
            e = env.unwrapped
            cube = e.cube().copy()
            act = sized_expert(env) if rate == "sized" else expert(env, rate)
            outcome = episode(env, act, obs)
            if outcome["catch"]:
                break
        records.append(
            {
                "seed": 30_000 + k,
                "cube_size": float(e.cube_size),
                "z": float(cube[2]),
                "radius": float(np.hypot(*cube[:2])),
                "azimuth_deg": float(np.degrees(np.arctan2(cube[1], cube[0]))),
                "rate": rate,
                **outcome,
            }
        )
    env.close()
    return records


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tests", type=int, default=100)
    args = parser.parse_args()
    path = RESULTS / "summary.json"
    summary = json.loads(path.read_text()) if path.exists() else {"settings": {}}
    summary["command"] = (
        f"PYTHONPATH=. python experiments/rl/trunk_debris_pull.py --tests {args.tests}"
    )
    for name, (kwargs, rates) in SETTINGS.items():
        done = summary["settings"].get(name)
        if done and len(done["episodes"]) == args.tests:
            continue
        env_kwargs = {"continuous_mode": "increment", "success": "catch", **kwargs}
        clock = time.perf_counter()
        records = play(env_kwargs, args.tests, rates)
        by_size = {
            str(s): float(np.mean([r["catch"] for r in records if r["cube_size"] == s]))
            for s in sorted({r["cube_size"] for r in records})
        }
        summary["settings"][name] = {
            "env_kwargs": env_kwargs,
            "rates": list(rates),
            "catch_rate": float(np.mean([r["catch"] for r in records])),
            "faces_at_end_2": float(np.mean([r["faces_at_end"] >= 2 for r in records])),
            "catch_rate_by_cube_size": by_size,
            "lost": int(sum(r["lost"] for r in records)),
            "diverged": int(sum(r["diverged"] for r in records)),
            "wall_seconds": time.perf_counter() - clock,
            "episodes": records,
        }
        write_json(path, summary)
        s = summary["settings"][name]
        print(name, s["catch_rate"], by_size, f"{s['wall_seconds']:.0f} s", flush=True)


if __name__ == "__main__":
    main()
