"""The Trunk proxy at coarser time steps (docs/proxy.md, "The proxy at its own time step"):
how well the calibrated proxy replays the FEM's pushes, and how fast, when its 0.3 s
environment step is taken in 30, 15 or 10 sub-steps (dt 0.01, 0.02, 0.03 s) while the FEM
keeps its 0.01 s.

The reference is the push calibration's (experiments/proxy_push_calibration.py: the FEM
Trunk's episodes by its five PPO policies and by random actions, recorded as the proxy's cable
actions with the FEM cube's track; made once into OUT/fem_pushes.npz, 43 episodes); the proxy
is a calibration report's ("parameters"), the optimisation / validation split the
calibration's (every other episode of each kind).

    python experiments/proxy_timestep.py [--calibration
        experiments/proxy/push_cocontraction/trunk-push_calibration.json] [--dt 0.01 0.02 0.03]

Writes experiments/results/proxy/timestep.json: per dt, the mean cube distance (mm) to the
FEM's over every step of each half, the cubes' mean travel, and the replay's wall time.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
import warnings
from pathlib import Path

import numpy as np

from pliant.proxy.calibrate import mean_distance
from pliant.proxy.pushes import Pushes, cube_travel, proxy_pushes

sys.path.insert(0, str(Path(__file__).parent))
from proxy_push_calibration import reference  # noqa: E402
from proxy_rl import SETTINGS  # noqa: E402

OUT = Path("experiments/results/proxy/timestep.json")


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
    args = parser.parse_args()
    warnings.simplefilter("ignore")
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
                "proxy_travel_mm": float(cube_travel(cubes).mean()),
                "replay_seconds": time.perf_counter() - clock,
            }
        )
        print(json.dumps(rows[-1]), flush=True)
    report = {
        "command": "python experiments/proxy_timestep.py " + " ".join(sys.argv[1:]),
        "calibration": str(args.calibration),
        "reference": str(args.reference),
        "episodes": len(fem.kinds),
        "fem_travel_mm": float(cube_travel(fem.cubes).mean()),
        "rows": rows,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(report, indent=1))


if __name__ == "__main__":
    main()
