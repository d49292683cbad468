"""The Trunk's default transfer (bend onto the cube, push it along x; `pliant proxy transfer
trunk`) repeated, for proxies touching with node balls or through the skinned FEM surface: the
runs are not bit-identical (the source is not pinned down: they differ with every thread
count at 1; contact amplifies whatever differs), so each proxy's relative reward difference
and final cube gap are reported over repeats (median, min, max).

    python experiments/proxy/trunk_repeats.py --repeats 5 \
        --proxy nodes= \
        --proxy surface=experiments/proxy/cube_surface/trunk-cube_calibration.json \
        --proxy surface_fem_mass=experiments/proxy/cube_surface/fem_mass.json \
        --out experiments/results/proxy/trunk_surface/repeats.json

(`nodes=` with no report: the calibrated defaults.) `--inverse-model sensitivity`: the
transfer's inverse model (`TransferGains.inverse_model`), the thesis' QP by default.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import warnings
from pathlib import Path

import numpy as np

from pliant.proxy.calibrate import fitted_proxy
from pliant.transfer.proxy import SEQUENCES, TRUNK_GAINS, trunk_transfer


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--proxy", action="append", required=True, help="NAME=[REPORT.json]")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--inverse-model", default="qp", choices=("qp", "sensitivity"))
    args = parser.parse_args()
    gains = dataclasses.replace(TRUNK_GAINS, inverse_model=args.inverse_model)
    warnings.simplefilter("ignore")
    result = {
        "command": "python experiments/proxy/trunk_repeats.py "
        + f"--repeats {args.repeats} "
        + " ".join(f"--proxy {p}" for p in args.proxy)
        + f" --out {args.out} --inverse-model {args.inverse_model}",
        "proxies": {},
    }
    for item in args.proxy:
        name, path = item.split("=", 1)
        env_kwargs = fitted_proxy(json.loads(Path(path).read_text())) if path else None
        runs = []
        for _ in range(args.repeats):
            run = trunk_transfer(env_kwargs=env_kwargs, gains=gains).run(list(SEQUENCES["trunk"]))
            runs.append(
                {
                    "relative_difference": run.relative_difference,
                    "final_gap_mm": run.final_gap,
                    "fem_travel_mm": run.fem_travel,
                }
            )
        summary = {}
        for key in ("relative_difference", "final_gap_mm", "fem_travel_mm"):
            values = np.array([r[key] for r in runs])
            summary[key] = {
                "median": float(np.median(values)),
                "min": float(values.min()),
                "max": float(values.max()),
            }
        result["proxies"][name] = {"report": path or None, "runs": runs, "summary": summary}
        print(name, json.dumps(summary), flush=True)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=1))


if __name__ == "__main__":
    main()
