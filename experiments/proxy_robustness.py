"""Robustness to the proxy's accuracy (thesis §4.1.3, Fig. 4.5 A-B), at a small scale: the
Multigait proxy's six calibrated parameters p become p (1 + level U(-1, 1)) (one draw, the
same for every level, scaled), PPO learns again on each degraded proxy, and each policy is
transferred to the FEM Multigait; the thesis finds that the reward still increases in every
case, levels 0.001 to 0.1.

    python experiments/proxy_robustness.py [--levels 0.001,0.01,0.1] [--env-steps 1440]
        [--transfer-steps 4]

Results: experiments/results/proxy/robustness.json and .png (forward travel against time, FEM
and proxy, one line per level); each policy in experiments/results/proxy/rl_multigait_noiseL/.

At a larger scale, around another calibration (its parameters and contact), several draws a
level (draw d: the noise of seed d, PPO seed d), each transferred open loop:

    python experiments/proxy_robustness.py --parameters REPORT.json --draws 3 \
        --feedforward 1 --tag _surface

writes robustness_surface.json and .png, the policies in rl_multigait_surface_noiseL_drawD/;
a run that stops goes on from the rows its report holds (the policy it was training is
trained again from the start).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
from proxy_rl import degraded, learn

from pliant.learn.evaluate import load_policy
from pliant.proxy.transfer import FORWARD, MULTIGAIT_GAINS, multigait_transfer

OUT = Path("experiments/results/proxy")


def transfer(policy_dir: Path, steps: int, feedforward: float = 0.0) -> dict:
    """The policy's strategy on its (degraded) proxy, followed by the FEM Multigait (by the
    inverse-QP loop, blended with `feedforward` of the proxy's actuation)."""
    saved = load_policy(policy_dir)
    gains = replace(MULTIGAIT_GAINS, feedforward=feedforward)
    loop = multigait_transfer(gains=gains, env_kwargs=saved.env_kwargs)
    result = loop.run(
        policy=lambda obs: saved.model.predict(saved.normalize_obs(obs), deterministic=True)[0],
        steps=steps,
    )
    proxy, fem = np.asarray(result.proxy_trajectory), np.asarray(result.fem_trajectory)
    return {
        "actions": [s.action for s in result.steps],
        "proxy_travel_mm": result.proxy_return,
        "fem_travel_mm": result.fem_return,
        "times": result.times,
        "proxy_forward_mm": ((proxy - proxy[0]) @ FORWARD).tolist(),
        "fem_forward_mm": ((fem - fem[0]) @ FORWARD).tolist(),
        "wall_seconds": result.wall_time,
    }


def plot(rows: list[dict], path: Path) -> None:
    from pliant.viz.render import offscreen_figure

    fig = offscreen_figure(10.0, 4.0)
    left, right = fig.subplots(1, 2)
    levels = sorted({row["level"] for row in rows})
    for row in rows:
        t, k = row["transfer"], levels.index(row["level"])
        label = f"noise {row['level']:g}" if row.get("draw", 0) == 0 else None
        left.plot(t["times"], t["fem_forward_mm"], f"C{k}-", label=label)
        right.plot(t["times"], t["proxy_forward_mm"], f"C{k}-", label=label)
    for ax, title in ((left, "A) FEM following each proxy"), (right, "B) each proxy")):
        ax.set_xlabel("time (s)")
        ax.set_ylabel("forward travel (mm)")
        ax.set_title(title)
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--levels", default="0.001,0.01,0.1")
    parser.add_argument("--env-steps", type=int, default=1440)
    parser.add_argument("--transfer-steps", type=int, default=4)
    parser.add_argument("--parameters", type=Path, default=None, help="a calibration report")
    parser.add_argument("--draws", type=int, default=None, help="draws a level (seeds 0..)")
    parser.add_argument("--feedforward", type=float, default=0.0, help="transfer's blend")
    parser.add_argument("--tag", default="", help="suffix of the report and policy folders")
    args = parser.parse_args()
    path = OUT / f"robustness{args.tag}.json"
    # One draw (seed 0) without --draws, named as before; a run with --draws resumes.
    draws = [None] if args.draws is None else list(range(args.draws))
    rows = json.loads(path.read_text())["rows"] if args.draws is not None and path.exists() else []
    done = {(row["level"], row.get("draw")) for row in rows}
    base = None if args.parameters is None else json.loads(args.parameters.read_text())
    for level in (float(v) for v in args.levels.split(",")):
        for draw in draws:
            if (level, draw) in done:
                continue
            clock = time.perf_counter()
            tag = f"{args.tag}_noise{level:g}" + ("" if draw is None else f"_draw{draw}")
            report = learn(
                "multigait",
                env_steps=args.env_steps,
                noise=level,
                seed=draw or 0,
                tag=tag,
                parameters=args.parameters,
            )
            fitted = base and base["parameters"]
            row = {
                "level": level,
                "draw": draw,
                "parameters": degraded("multigait", level, draw or 0, fitted),
                "proxy_episode_travel_mm": report["evaluation"]["learned"]["travel_mm"],
                "learned_actions": report["evaluation"]["learned_actions"],
                "training_seconds": report["training_seconds"],
                "transfer": transfer(
                    OUT / f"rl_multigait{tag}", args.transfer_steps, args.feedforward
                ),
                "wall_seconds": time.perf_counter() - clock,
            }
            rows.append(row)
            t = row["transfer"]
            print(
                f"noise {level:g} draw {draw}: proxy episode {row['proxy_episode_travel_mm']:.2f}"
                f" mm; transfer proxy {t['proxy_travel_mm']:.2f} / FEM {t['fem_travel_mm']:.2f}"
                " mm",
                flush=True,
            )
            report = {
                "command": "python experiments/proxy_robustness.py " + " ".join(sys.argv[1:]),
                "env_steps": args.env_steps,
                "transfer_steps": args.transfer_steps,
                "parameters": None if args.parameters is None else str(args.parameters),
                "feedforward": args.feedforward,
                "rows": rows,
            }
            path.write_text(json.dumps(report, indent=1))
            plot(rows, path.with_suffix(".png"))


if __name__ == "__main__":
    main()
