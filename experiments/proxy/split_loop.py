"""The Multigait's transfer with the work split between the thesis' two loops: the inverse
model tracks the body (the centre's 3 skeleton nodes and the root half of each leg, 11 of the
19 matched points) and the tip-angle corrector alone owns each leg's last segment (thesis
L706, L714: the inverse model "ignores the angle of incidence of contact points", which the
corrector adds). Tested reading: with every point in the inverse model, the inverse model and
the corrector pull the legs' tips towards two different goals.

    python experiments/proxy/split_loop.py --out experiments/results/proxy/split_loop.json

The thesis' test sequence [4,0,0,2,5,1,3,4] on the default proxy, the thesis' gains
(:data:`pliant.transfer.proxy.MULTIGAIT_GAINS`, frictionless look-ahead), corrector gains 0.5
and 1 with the inverse QP, and 0.5 with the sensitivity model (look-ahead 1); each case's
per-step rewards, matched-point errors and chamber volumes at each step's end. About 5
minutes on one core; the JSON is rewritten (atomically) after each case and a rerun skips the
cases done.
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from pliant.condensed.dataset import atomic_write
from pliant.solvers import ImplicitEuler
from pliant.transfer.proxy import (
    MULTIGAIT_GAINS,
    EmbeddedPoints,
    MultigaitTransfer,
    multigait_transfer,
    with_effector,
)

SEQUENCE = (4, 0, 0, 2, 5, 1, 3, 4)
CASES = {
    "qp_gain0.5": ("qp", 0.5),
    "qp_gain1": ("qp", 1.0),
    "sensitivity_gain0.5": ("sensitivity", 0.5),
}


def body_nodes(n_nodes: int, tip_nodes: int = 2) -> np.ndarray:
    """The skeleton's nodes the inverse model tracks: all but each leg's last `tip_nodes`."""
    keep = np.ones(n_nodes, dtype=bool)
    for nodes in MultigaitTransfer.LEGS.values():
        keep[nodes[len(nodes) - tip_nodes :]] = False
    return np.flatnonzero(keep)


def split_transfer(model: str, angle_gain: float) -> MultigaitTransfer:
    """The default Multigait transfer whose inverse model sees the body nodes only; the
    corrector, the realignment and the records keep all 19 points."""
    gains = replace(
        MULTIGAIT_GAINS,
        angle_gain=angle_gain,
        inverse_model=model,
        inverse_steps=1 if model == "sensitivity" else MULTIGAIT_GAINS.inverse_steps,
    )
    t = multigait_transfer(gains=gains)
    rod = t.env.proxy.rod
    body = body_nodes(rod.n_centreline)
    tracked = EmbeddedPoints(
        t.fem.body.mesh,
        rod.centreline(rod.rest_positions)[body],
        tolerance=5.0,
        outside="keep",
    )
    t.fem = with_effector(t.fem, tracked)  # the records keep t.points: all 19
    t.solver = ImplicitEuler(t.fem, dt=t.env.dt / gains.fem_substeps)
    qp_inverse, roll_out, sensitivity = t.qp_inverse, t.roll_out, t.sensitivity_inverse
    t.qp_inverse = lambda target: qp_inverse(target[body])
    t.roll_out = lambda actuation: roll_out(actuation)[body]
    t.sensitivity_inverse = lambda target: sensitivity(target[body])
    return t


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--out", type=Path, default=Path("experiments/results/proxy/split_loop.json")
    )
    args = parser.parse_args()
    report = json.loads(args.out.read_text()) if args.out.exists() else {}
    for name, (model, gain) in CASES.items():
        if name in report:
            continue
        t = split_transfer(model, gain)
        clock = time.perf_counter()
        result = t.run(list(SEQUENCE))
        volumes = np.asarray(result.actuation)[
            t.gains.scale * t.gains.fem_substeps - 1 :: t.gains.scale * t.gains.fem_substeps
        ]
        report[name] = {
            "inverse_model": model,
            "angle_gain": gain,
            "proxy_distance_mm": result.proxy_return,
            "fem_distance_mm": result.fem_return,
            "relative_difference": result.relative_difference,
            "steps": [
                {
                    "action": s.action,
                    "proxy_mm": s.proxy_reward,
                    "fem_mm": s.fem_reward,
                    "tracking_error_mm": s.tracking_error,
                    "volumes_mm3": v.round(1).tolist(),
                }
                for s, v in zip(result.steps, volumes, strict=True)
            ],
            "wall_time_s": time.perf_counter() - clock,
        }
        report["command"] = "python experiments/proxy/split_loop.py --out " + str(args.out)
        atomic_write(args.out, lambda tmp: Path(tmp).write_text(json.dumps(report, indent=1)))
        print(f"{name}: proxy {result.proxy_return:.2f} mm, FEM {result.fem_return:.2f} mm")


if __name__ == "__main__":
    main()
