"""Node balls against the skinned FEM surface as the Multigait proxy's contact (issue 18): each
calibrated proxy replayed on one FEM trajectory, with its matched-point error, its travel error
and its centroid's move over each 0.6 s action beside the FEM's.

    python experiments/proxy/contact.py \
        --proxy nodes=experiments/proxy/travel/multigait-joint_calibration.json \
        --proxy surface=experiments/proxy/surface/multigait-joint_calibration.json \
        --reference experiments/proxy/iterate/multigait-iterate_reference.npz \
        --out experiments/results/proxy/contact/iterate.json

The reference is made by experiments/proxy/iterate_calibration.py (the joint calibration's
actions, then a learned gait's); the JSON lists the actions, and the moves of the last
`--last` of them (the learned gait) are printed side by side.
"""

from __future__ import annotations

import argparse
import json
import time
import warnings
from pathlib import Path

import numpy as np

from pliant.proxy.calibrate import fitted_proxy, mean_distance, travel, travel_error
from pliant.proxy.references import MULTIGAIT_ACTION, Reference, setup


def replay(report: Path, reference: Reference) -> dict:
    """The report's proxy (its fitted parameters and contact) on the reference."""
    fitted = json.loads(report.read_text())
    contact = fitted.get("contact", "nodes")
    start = time.perf_counter()
    points = setup("multigait").simulate(reference)(fitted_proxy(fitted))
    interval = round(MULTIGAIT_ACTION / reference.dt)
    return {
        "report": str(report),
        "contact": contact,
        "parameters": fitted["parameters"],
        "seconds": time.perf_counter() - start,
        "points_error_mm": mean_distance(reference.points, points),
        "travel_error_mm": travel_error(reference.points, points, interval),
        "travel_mm": travel(points, interval).round(3).tolist(),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--proxy", action="append", required=True, help="NAME=REPORT.json")
    parser.add_argument("--reference", type=Path, required=True)
    parser.add_argument("--last", type=int, default=12, help="actions printed side by side")
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args()
    warnings.simplefilter("ignore")
    reference = Reference.load(args.reference)
    interval = round(MULTIGAIT_ACTION / reference.dt)
    fem = travel(reference.points, interval)
    result = {
        "command": "python experiments/proxy/contact.py "
        + " ".join(f"--proxy {p}" for p in args.proxy)
        + f" --reference {args.reference} --out {args.out}",
        "reference": str(args.reference),
        "fem_travel_mm": fem.round(3).tolist(),
        "proxies": {},
    }
    print("FEM      ", np.round(fem[-args.last :, 0], 2), f"sum {fem[-args.last :, 0].sum():.2f}")
    for item in args.proxy:
        name, path = item.split("=", 1)
        run = replay(Path(path), reference)
        result["proxies"][name] = run
        x = np.array(run["travel_mm"])[-args.last :, 0]
        print(
            f"{name:9s}",
            np.round(x, 2),
            f"sum {x.sum():.2f}",
            f"points {run['points_error_mm']:.2f} mm, travel {run['travel_error_mm']:.2f} mm",
        )
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=1))


if __name__ == "__main__":
    main()
