"""The Multigait's actuation correction on top of the open-loop transfer: each learned policy's
8 steps replayed on the FEM as volumes (``--feedforward 1``, realignment every 7 steps), with
the tip-angle corrector (thesis Fig. 4.2.2, :mod:`pliant.transfer.proxy`) at several gains,
0 the plain open loop. One ``pliant proxy transfer`` a (policy, gain), two at a time; each
transfer's JSON in OUT/NAME/gainG/, the summary in OUT/corrector.json and .png.

    python experiments/proxy/corrector.py --out experiments/results/proxy/corrector

Policies: PPO on the surface-contact proxy (``rl_multigait_surface``) and the 12 of the
robustness study around it (4 noise levels x 3 draws, PPO seed = draw,
``rl_multigait_surface_noise*``), PPO on the node-ball travel proxy (``rl_multigait_travel``)
and on the proxy bent about its underside (``rl_multigait_underside``); then the thesis' test
sequence on the surface and node-ball proxies. About 16 s a transfer on one core.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from pliant.transfer.batch import run_jobs  # noqa: E402
from pliant.viz import save_figure

RESULTS = Path("experiments/results/proxy")
CALIBRATIONS = Path("experiments/proxy")


def cases() -> dict[str, list[str]]:
    """name -> the transfer's source options."""
    out = {"surface": ["--policy", str(RESULTS / "rl_multigait_surface"), "--steps", "8"]}
    for level in ("0", "0.001", "0.01", "0.1"):
        for draw in range(3):
            name = f"surface_noise{level}_draw{draw}"
            out[name] = ["--policy", str(RESULTS / f"rl_multigait_{name}"), "--steps", "8"]
    out["travel"] = ["--policy", str(RESULTS / "rl_multigait_travel"), "--steps", "8"]
    out["underside"] = ["--policy", str(RESULTS / "rl_multigait_underside"), "--steps", "8"]
    for name, folder in (("sequence_surface", "surface"), ("sequence_travel", "travel")):
        out[name] = ["--proxy", str(CALIBRATIONS / folder / "multigait-joint_calibration.json")]
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--gains", default="0,0.25,0.5,1")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--out", type=Path, default=RESULTS / "corrector")
    args = parser.parse_args()
    gains = [float(g) for g in args.gains.split(",")]
    env = {**os.environ, "OMP_NUM_THREADS": "1", "NUMBA_NUM_THREADS": "1"}
    env["OPENBLAS_NUM_THREADS"] = "1"
    jobs = []
    for name, source in cases().items():
        for gain in gains:
            folder = args.out / name / f"gain{gain:g}"
            if not (folder / "multigait_transfer.json").exists():  # resume: done ones stay
                command = ["pliant", "proxy", "transfer", "multigait", *source]
                command += ["--feedforward", "1", "--angle-gain", f"{gain:g}", "--out", str(folder)]
                jobs.append(command)
    run_jobs(jobs, args.workers, env)

    rows = []
    for name in cases():
        for gain in gains:
            path = args.out / name / f"gain{gain:g}" / "multigait_transfer.json"
            if not path.exists():
                print(f"missing: {path}", file=sys.stderr)
                continue
            report = json.loads(path.read_text())
            proxy, fem = report["proxy_return"], report["fem_return"]
            rows.append(
                {
                    "case": name,
                    "angle_gain": gain,
                    "actions": [s["action"] for s in report["steps"]],
                    "proxy_travel_mm": round(proxy, 3),
                    "fem_travel_mm": round(fem, 3),
                    "relative_difference": round(report["relative_difference"], 4),
                }
            )
    summary = {"command": "python experiments/proxy/corrector.py " + " ".join(sys.argv[1:])}
    summary["gains"] = gains
    summary["rows"] = rows
    for gain in gains:
        diffs = [r["relative_difference"] for r in rows if r["angle_gain"] == gain]
        summary[f"gain{gain:g}"] = {
            "median_relative_difference": float(np.median(diffs)),
            "within_5_percent": int(sum(d <= 0.05 for d in diffs)),
            "cases": len(diffs),
        }
        print(f"gain {gain:g}: {summary[f'gain{gain:g}']}")
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "corrector.json").write_text(json.dumps(summary, indent=1))

    names = list(cases())
    fig, ax = plt.subplots(figsize=(10, 4))
    width = 0.8 / len(gains)
    for k, gain in enumerate(gains):
        value = {r["case"]: 100 * r["relative_difference"] for r in rows if r["angle_gain"] == gain}
        ax.bar(
            np.arange(len(names)) + k * width,
            [value.get(n, np.nan) for n in names],
            width,
            label=f"angle gain {gain:g}",
        )
        heights = [value.get(n, 0.0) for n in names]
        for x, v in zip(np.arange(len(names)) + k * width, heights, strict=True):
            if v > 50.0:  # off the axis: its value written at the top
                ax.text(x, 49.0, f"{v:.0f}", ha="center", va="top", fontsize=6, rotation=90)
    ax.set_ylim(0.0, 50.0)
    ax.axhline(5.0, color="k", lw=0.8, ls="--", label="thesis 5 %")
    ax.set_xticks(np.arange(len(names)) + 0.4 - width / 2, names, rotation=60, ha="right")
    ax.set_ylabel("|proxy - FEM| / FEM travel (%)")
    ax.set_title("Multigait open-loop transfer with the tip-angle corrector")
    ax.legend(fontsize=7)
    fig.tight_layout()
    save_figure(fig, args.out / "corrector.png", dpi=110)


if __name__ == "__main__":
    main()
