"""The thesis' Multigait loop as the authors built it (session 38): the twin FEM under the
inverse QP (``--inverse-model twin``), effectors on the underside (``--matched underside``)
and the tip-angle corrector, against the look-ahead QP, on the thesis' test sequence, the
learned policy of the surface proxy and PPO's other seeds, and the other proxies. One
``pliant proxy transfer multigait`` a case, two at a time, each into its own folder under
experiments/results/proxy/ (a case whose JSON is there is not run again); the summary in
experiments/results/proxy/twin_summary.json and .png.

    python experiments/proxy/twin.py

About 2 minutes a case on one core (the travel proxy's 5.5: its twin diverges and is
registered again); 18 cases.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from pliant.files import write_json  # noqa: E402
from pliant.transfer.batch import run_transfers  # noqa: E402
from pliant.transfer.reports import transfer_row  # noqa: E402
from pliant.viz import save_figure

RESULTS = Path("experiments/results/proxy")
CALIBRATIONS = Path("experiments/proxy")
TWIN = ["--inverse-model", "twin"]
UNDER = ["--matched", "underside"]
CORRECTOR = ["--angle-gain", "0.5"]


def cases() -> dict[str, tuple[list[str], Path]]:
    """name -> (the transfer's options, its output folder)."""
    out: dict[str, tuple[list[str], Path]] = {
        "sequence, twin": (TWIN, RESULTS / "twin"),
        "sequence, twin, corrector": (TWIN + CORRECTOR, RESULTS / "twin_corrector"),
        "sequence, twin, underside": (TWIN + UNDER, RESULTS / "twin_underside"),
        "sequence, twin, underside, corrector": (
            TWIN + UNDER + CORRECTOR,
            RESULTS / "twin_underside_corrector",
        ),
        "sequence, look-ahead, underside": (UNDER, RESULTS / "underside"),
    }
    for proxy in ("surface", "joint", "travel"):
        report = CALIBRATIONS / proxy / "multigait-joint_calibration.json"
        out[f"sequence, {proxy} proxy, twin, underside, corrector"] = (
            ["--proxy", str(report), *TWIN, *UNDER, *CORRECTOR],
            RESULTS / f"{proxy}_twin_underside_corrector",
        )
    policy = RESULTS / "rl_multigait_surface"
    for tag, options in (
        ("twin, corrector", TWIN + CORRECTOR),
        ("twin, underside", TWIN + UNDER),
        ("twin, underside, corrector", TWIN + UNDER + CORRECTOR),
    ):
        folder = policy / tag.replace(", ", "_")
        out[f"policy, {tag}"] = (["--policy", str(policy), "--steps", "8", *options], folder)
    for seed in range(1, 8):
        policy = RESULTS / f"rl_multigait_surface_seed{seed}"
        out[f"policy seed {seed}, twin, underside, corrector"] = (
            ["--policy", str(policy), "--steps", "8", *TWIN, *UNDER, *CORRECTOR],
            policy / "twin_underside_corrector",
        )
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    run_transfers(cases().values(), args.workers)

    rows = [transfer_row(name, folder, options) for name, (options, folder) in cases().items()]
    rows = [r for r in rows if r is not None]
    for r in rows:
        print(f"{r['case']}: proxy {r['proxy_travel_mm']:.2f} FEM {r['fem_travel_mm']:.2f} mm")
    summary = {"command": "python experiments/proxy/twin.py " + " ".join(sys.argv[1:])}
    summary["rows"] = rows
    write_json(RESULTS / "twin_summary.json", summary)

    fig, (left, right) = plt.subplots(1, 2, figsize=(12, 4.5), width_ratios=[1, 1.4])
    head = next(r for r in rows if r["case"] == "sequence, twin, underside, corrector")
    x = range(len(head["proxy_steps_mm"]))
    left.bar([k - 0.2 for k in x], head["proxy_steps_mm"], 0.4, label="proxy")
    left.bar([k + 0.2 for k in x], head["fem_steps_mm"], 0.4, label="FEM")
    left.set_xticks(list(x), [str(a) for a in head["actions"]])
    left.set_xlabel("action of the thesis' test sequence")
    left.set_ylabel("forward travel over the step (mm)")
    left.set_title("twin, underside effectors, corrector 0.5")
    left.legend()
    right.barh(
        [r["case"] for r in rows], [100 * (r["fem_over_proxy"] or 0.0) for r in rows], color="C1"
    )
    right.axvline(95.0, color="k", ls="--", lw=0.8, label="thesis: within 5 %")
    right.set_xlabel("FEM travel / proxy travel (%)")
    right.invert_yaxis()
    right.tick_params(axis="y", labelsize=7)
    right.legend(fontsize=7)
    fig.tight_layout()
    save_figure(fig, RESULTS / "twin_summary.png", dpi=110)


if __name__ == "__main__":
    main()
