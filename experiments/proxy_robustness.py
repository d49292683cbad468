"""Robustness to the proxy's accuracy (thesis §4.1.3, Fig. 4.5 A-B), at a small scale: the
Multigait proxy's six calibrated parameters p become p (1 + level U(-1, 1)) (one draw, the
same for every level, scaled), PPO learns again on each degraded proxy, and each policy is
transferred to the FEM Multigait; the thesis finds that the reward still increases in every
case, levels 0.001 to 0.1.

    python experiments/proxy_robustness.py [--levels 0.001,0.01,0.1] [--env-steps 1440]
        [--transfer-steps 4]

Results: experiments/results/proxy/robustness.json and .png (forward travel against time, FEM
and proxy, one line per level); each policy in experiments/results/proxy/rl_multigait_noiseL/.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
from proxy_rl import degraded, learn

from pliant.learn.evaluate import load_policy
from pliant.proxy.transfer import FORWARD, multigait_transfer

OUT = Path("experiments/results/proxy")


def transfer(policy_dir: Path, steps: int) -> dict:
    """The policy's strategy on its (degraded) proxy, followed by the FEM Multigait."""
    saved = load_policy(policy_dir)
    loop = multigait_transfer(env_kwargs=saved.env_kwargs)
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
    for k, row in enumerate(rows):
        t = row["transfer"]
        label = f"noise {row['level']:g}"
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
    args = parser.parse_args()
    rows = []
    for level in (float(v) for v in args.levels.split(",")):
        clock = time.perf_counter()
        report = learn("multigait", env_steps=args.env_steps, noise=level, tag=f"_noise{level:g}")
        row = {
            "level": level,
            "parameters": degraded("multigait", level, 0),
            "proxy_episode_travel_mm": report["evaluation"]["learned"]["travel_mm"],
            "learned_actions": report["evaluation"]["learned_actions"],
            "training_seconds": report["training_seconds"],
            "transfer": transfer(OUT / f"rl_multigait_noise{level:g}", args.transfer_steps),
            "wall_seconds": time.perf_counter() - clock,
        }
        rows.append(row)
        t = row["transfer"]
        print(
            f"noise {level:g}: proxy episode {row['proxy_episode_travel_mm']:.2f} mm; transfer"
            f" proxy {t['proxy_travel_mm']:.2f} / FEM {t['fem_travel_mm']:.2f} mm",
            flush=True,
        )
        report = {
            "command": "python experiments/proxy_robustness.py " + " ".join(sys.argv[1:]),
            "env_steps": args.env_steps,
            "transfer_steps": args.transfer_steps,
            "rows": rows,
        }
        (OUT / "robustness.json").write_text(json.dumps(report, indent=1))
        plot(rows, OUT / "robustness.png")


if __name__ == "__main__":
    main()
