"""Where the Multigait proxy's travel differs from the FEM's: a fixed action sequence replayed
open loop on both (the transfer's ``--feedforward 1``, no realignment), and after each action
the forward move of the body's parts, read on the same matched points (the skeleton's 19
nodes, embedded in the FEM body): the centre's three nodes, each leg pair's eight, the leg
pairs' tips; and each model's centre of mass (the environment's reward) beside the points'
centroid weighted by the FEM's own mass distribution (the FEM's node masses lumped on the
nearest skeleton node), the same measure for both models.

    python experiments/proxy/gait_parts.py \\
        --policy experiments/results/proxy/rl_multigait_surface --actions 4,2,5,3,4,2,5,3 \\
        --out experiments/results/proxy/gait_parts/surface.json

``--policy`` takes the proxy environment's keywords (fitted parameters, contact) from a
policy's ``meta.json``; ``--proxy REPORT`` from a calibration report. Discrete(6) actions: 2 g
inflates group g of (centre, front pair, rear pair), 2 g + 1 deflates it. About 20 s.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
from pathlib import Path

import numpy as np

from pliant.envs.multigait import FORWARD
from pliant.proxy.calibrate import fitted_proxy
from pliant.transfer.proxy import MULTIGAIT_GAINS, multigait_transfer

#: the skeleton's nodes (pliant.proxy.builders.multigait_proxy): the centre, then 4 a leg in
#: the order front left, front right, rear left, rear right, root to tip.
PARTS = {
    "centre": [0, 1, 2],
    "front legs": list(range(3, 11)),
    "rear legs": list(range(11, 19)),
    "front tips": [6, 10],
    "rear tips": [14, 18],
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    source = parser.add_mutually_exclusive_group(required=True)
    source.add_argument("--policy", type=Path, help="a policy folder (its meta.json)")
    source.add_argument("--proxy", type=Path, help="a calibration report (JSON)")
    parser.add_argument("--actions", default="4,2,5,3,4,2,5,3")
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args()
    if args.policy is not None:
        env_kwargs = json.loads((args.policy / "meta.json").read_text())["env_kwargs"]
    else:
        env_kwargs = fitted_proxy(json.loads(args.proxy.read_text()))
    actions = [int(a) for a in args.actions.split(",")]

    gains = dataclasses.replace(MULTIGAIT_GAINS, feedforward=1.0, time_register=0)
    transfer = multigait_transfer(gains=gains, env_kwargs=env_kwargs)
    rod, fem = transfer.env.proxy.rod, transfer.fem.body
    rest = rod.centreline(rod.rest_positions)
    nearest = np.argmin(np.linalg.norm(fem.rest_positions[:, None, :] - rest[None], axis=2), axis=1)
    fem_weights = np.bincount(nearest, weights=fem.node_masses, minlength=len(rest))
    fem_weights /= fem_weights.sum()

    def snapshot() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        return (
            transfer.proxy_points(transfer.env.state.positions),
            transfer.points.positions(transfer.state.positions),
            transfer.proxy_position(transfer.env.state),
            transfer.fem_position(transfer.state),
        )

    frames = [snapshot()]
    for action in actions:
        transfer.step(action)
        frames.append(snapshot())
    proxy_points, fem_points, proxy_com, fem_com = (np.array(f) for f in zip(*frames, strict=True))

    def moves(series: np.ndarray) -> list[float]:
        return np.round(np.diff(series @ FORWARD), 3).tolist()

    report: dict = {
        "command": "python experiments/proxy/gait_parts.py "
        + (f"--policy {args.policy}" if args.policy else f"--proxy {args.proxy}")
        + f" --actions {args.actions} --out {args.out}",
        "env_kwargs": env_kwargs,
        "actions": actions,
        "moves_mm": {},
        "heights_mm": {},
    }
    for name, points in (("proxy", proxy_points), ("fem", fem_points)):
        parts = {"centre of mass (reward)": moves(proxy_com if name == "proxy" else fem_com)}
        parts["points, FEM mass weights"] = moves(np.einsum("k,tkd->td", fem_weights, points))
        for part, nodes in PARTS.items():
            parts[part] = moves(points[:, nodes].mean(axis=1))
        report["moves_mm"][name] = parts
        report["heights_mm"][name] = {
            part: np.round(points[:, PARTS[part], 2].mean(axis=1), 2).tolist()
            for part in ("centre", "front tips", "rear tips")
        }
    for part in report["moves_mm"]["proxy"]:
        p, f = report["moves_mm"]["proxy"][part], report["moves_mm"]["fem"][part]
        row = " ".join(f"{a:6.2f}/{b:<6.2f}" for a, b in zip(p, f, strict=True))
        print(f"{part:26s} proxy/FEM {row} total {sum(p):.2f}/{sum(f):.2f}")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(report, indent=1))


if __name__ == "__main__":
    main()
