"""The Trunk proxy's cube fitted on the FEM's pushes (docs/proxy.md, "A proxy fitted on the
FEM's pushes"): the proxy's trunk stays as its calibration made it (the shortening beams of
experiments/proxy/contraction/trunk_calibration.json); what the cube does when the trunk
strikes it is fitted to what the FEM's cube does under the same actuation
(:mod:`pliant.transfer.pushes`).

Reference (made once, kept in OUT/fem_pushes.npz): whole episodes of the FEM task
(pliant/TrunkPush-v0 with 14/8 mm courses, 10 steps of 0.3 s), by the five PPO policies learnt
on the FEM (experiments/results/proxy/fem_vs_proxy/std1[_seedS], greedy, goals of seeds 3000
on: none of the 20 evaluation goals 1000-1019) and by random actions around the middle of the
box (std 1 and 0.37: PPO's initial exploration with SB3's default and with log_std_init -1);
random episodes whose cube moved less than 2 mm are left out (they carry no information).
Episodes alternate between optimisation and validation within each kind.

Search (Optuna TPE, study resumed from OUT/push.db; the first trial is the proxy as it was):
the cube's mass, its Coulomb coefficient, its velocity damping, the radius of the trunk's
contact balls (its bending section keeps the calibrated 10 mm) and the trunk's Rayleigh mass
damping. Loss: the mean distance (mm) between the FEM's and the proxy's cube centres over
every step of the optimisation episodes.

    python experiments/proxy/push_calibration.py [--trials 120] [--out experiments/proxy/push]

``--base REPORT.json`` fits the cube on another calibrated trunk (e.g. the axial commands of
experiments/proxy/cocontraction_calibration.py), ``--start REPORT.json`` tries a previous
push calibration's fitted values first instead of the proxy as it was, ``--reference NPZ``
reuses another run's FEM pushes.

Writes OUT/trunk-push_calibration.json: a calibration report whose "parameters" are the
contraction calibration's with the fitted ones (``proxy/rl.py --parameters`` reads it), the
errors before and after by kind of episode, the cube's travel on both models.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
import warnings
from pathlib import Path

import numpy as np

from pliant.proxy.calibrate import calibrate, mean_distance
from pliant.transfer.pushes import Pushes, cube_travel, proxy_pushes
from pliant.transfer.pushes import reference_pushes as reference
from pliant.transfer.rl import SETTINGS

CONTRACTION = Path("experiments/proxy/contraction/trunk_calibration.json")
SPACE = {
    "cube_mass": (0.002, 0.05),
    "cube_friction": (0.05, 1.0),
    "cube_damping": (0.0, 20.0),
    "contact_radius": (4.0, 14.0),
    "rayleigh_mass": (0.01, 2.0),
}
#: the proxy as it was (builder defaults), the search's first trial
START = {
    "cube_mass": 0.01,
    "cube_friction": 0.3,
    "cube_damping": 0.0,
    "contact_radius": 10.0,
    "rayleigh_mass": 0.1,
}


def errors_by_kind(fem: Pushes, proxy: np.ndarray) -> dict:
    """Mean cube distance (mm) per kind of episode, optimisation and validation halves."""
    rows = {}
    for kind in dict.fromkeys(fem.kinds):
        index = np.flatnonzero(fem.kinds == kind)
        rows[kind] = {
            "episodes": len(index),
            "error_mm": mean_distance(fem.cubes[index], proxy[index]),
            "fem_travel_mm": float(cube_travel(fem.cubes[index]).mean()),
            "proxy_travel_mm": float(cube_travel(proxy[index]).mean()),
        }
    return rows


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--trials", type=int, default=120)
    parser.add_argument("--per-policy", type=int, default=4)
    parser.add_argument("--random-episodes", type=int, default=24)
    parser.add_argument("--moved", type=float, default=2.0, help="mm a random episode must push")
    parser.add_argument("--out", type=Path, default=Path("experiments/proxy/push"))
    parser.add_argument("--base", type=Path, default=CONTRACTION, help="the trunk's calibration")
    parser.add_argument("--start", type=Path, default=None, help="a push calibration to try first")
    parser.add_argument(
        "--reference", type=Path, default=None, help="the FEM's pushes (default OUT/fem_pushes.npz)"
    )
    args = parser.parse_args()
    warnings.simplefilter("ignore")
    args.out.mkdir(parents=True, exist_ok=True)
    path = args.reference or args.out / "fem_pushes.npz"
    if path.exists():
        fem = Pushes.load(path)
    else:
        clock = time.perf_counter()
        fem = reference(args.per_policy, args.random_episodes, args.moved)
        fem.save(path)
        print(f"FEM reference: {len(fem.kinds)} episodes in {time.perf_counter() - clock:.0f} s")
    # Alternate optimisation / validation within each kind: order the episodes so that the
    # calibration's every-2nd split (0, 2, 4, ... optimise) takes every other one of a kind.
    order = np.concatenate([np.flatnonzero(fem.kinds == kind) for kind in dict.fromkeys(fem.kinds)])
    fem = Pushes(fem.actions[order], fem.cubes[order], fem.kinds[order])
    contraction = json.loads(args.base.read_text())
    start = START if args.start is None else json.loads(args.start.read_text())["fitted"]
    base = {**SETTINGS["trunk"]["env_kwargs"], **contraction["parameters"]}

    def simulate(parameters: dict) -> np.ndarray:
        return proxy_pushes(fem, {**base, **parameters})

    clock = time.perf_counter()
    result = calibrate(
        simulate,
        fem.cubes,  # episodes are the "positions", their steps' cube centres the points
        SPACE,
        trials=args.trials,
        storage=f"sqlite:///{args.out / 'push.db'}",
        study_name="trunk-push",
        every=2,
        start=start,
    )
    seconds = time.perf_counter() - clock
    before, after = simulate(START), simulate(result.parameters)
    optimise, validate = np.arange(0, len(fem.kinds), 2), np.arange(1, len(fem.kinds), 2)
    report = {
        "robot": "trunk-push",
        "command": "python experiments/proxy/push_calibration.py " + " ".join(sys.argv[1:]),
        "trials": result.trials,
        "optimisation_error_mm": result.optimisation_error,
        "validation_error_mm": result.validation_error,
        "before": {
            "optimisation_error_mm": mean_distance(fem.cubes[optimise], before[optimise]),
            "validation_error_mm": mean_distance(fem.cubes[validate], before[validate]),
        },
        "parameters": {**contraction["parameters"], **result.parameters},
        "fitted": result.parameters,
        "space": SPACE,
        "start": start,
        "base_calibration": str(args.base),
        "contact": contraction.get("contact", "nodes"),
        "reference": str(path),
        "episodes": len(fem.kinds),
        "by_kind_before": errors_by_kind(fem, before),
        "by_kind_after": errors_by_kind(fem, after),
        "seconds_this_run": seconds,
    }
    (args.out / "trunk-push_calibration.json").write_text(json.dumps(report, indent=1))
    print(json.dumps({k: v for k, v in report.items() if not k.startswith("by_kind")}, indent=1))
    for name in ("by_kind_before", "by_kind_after"):
        print(name, json.dumps(report[name]))


if __name__ == "__main__":
    main()
