"""The Multigait's thesis loop with a prior in its inverse QP (session 40): the twin FEM under
the inverse QP, effectors on the underside, the tip-angle corrector (the arrangement of
experiments/proxy/twin.py), and the QP's regularisation pulling the chambers towards the
proxy's commands mapped onto them (``--prior-weight W``) instead of towards zero pressure.

The points do not tell the FEM's actuations apart where the proxy's shape is one the FEM
reaches by several (the centre on, or the centre off with the legs half inflated: docs/proxy.md,
"Why the inverse model keeps the centre low"); the default regularisation then picks the
weakest. The prior picks the proxy's own. Cases: the weights 0.1, 1, 3, 10 and 30 (0 is
proxy/twin.py's case) on the thesis' test sequence and on the learned policy
(``rl_multigait_surface``, 8 steps); at 10, the other PPO seeds' policies, the policy without
the corrector, the policy by the look-ahead QP restarted from the FEM at each sub-step (the
loop's first reading, matched points at mid-thickness or on the underside) instead of the
twin, and the test sequence on the surface proxy. One ``pliant proxy transfer
multigait`` a case, two at a time, each into its own folder (a case whose JSON is there is not
run again); the summary in experiments/results/proxy/prior_summary.json and .png. At 10 also
the two policies PPO learned on the node-ball proxy (``rl_multigait``, observing the points and
the commands; ``rl_multigait_points``, the points only, the thesis' observation). Then, at 10,
the 12 policies of the robustness study (thesis §4.1.3: PPO again on the surface proxy with
its parameters perturbed by 0, 0.1, 1 and 10 %, three draws each;
experiments/proxy/robustness.py), beside their open-loop transfers with the corrector
(experiments/results/proxy/corrector/corrector.json).

    python experiments/proxy/prior.py

About 2 minutes a case on one core; 35 cases.
"""

from __future__ import annotations

import argparse
import json
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
LOOP = ["--inverse-model", "twin", "--matched", "underside"]
CORRECTOR = ["--angle-gain", "0.5"]
WEIGHTS = (0.1, 1.0, 3.0, 10.0, 30.0)
HEADLINE = 10.0
SEEDS = range(1, 8)
LEVELS = ("0", "0.001", "0.01", "0.1")
DRAWS = range(3)


def prior(weight: float) -> list[str]:
    return ["--prior-weight", f"{weight:g}"]


def at_headline(folder: Path) -> tuple[list[str], Path, float]:
    """The case of the policy in `folder` (8 steps) by the loop with the corrector and the
    prior at the headline weight, written beside it."""
    options = ["--policy", str(folder), "--steps", "8", *LOOP, *CORRECTOR, *prior(HEADLINE)]
    return options, folder / f"twin_underside_corrector_prior{HEADLINE:g}", HEADLINE


def cases() -> dict[str, tuple[list[str], Path, float]]:
    """name -> (the transfer's options, its output folder, the prior's weight)."""
    out: dict[str, tuple[list[str], Path, float]] = {}
    policy = RESULTS / "rl_multigait_surface"
    learned = ["--policy", str(policy), "--steps", "8"]
    for w in WEIGHTS:
        out[f"policy, prior {w:g}"] = (
            learned + LOOP + CORRECTOR + prior(w),
            policy / f"twin_underside_corrector_prior{w:g}",
            w,
        )
    for w in WEIGHTS:
        out[f"sequence, prior {w:g}"] = (
            LOOP + CORRECTOR + prior(w),
            RESULTS / f"twin_underside_corrector_prior{w:g}",
            w,
        )
    for seed in SEEDS:
        folder = RESULTS / f"rl_multigait_surface_seed{seed}"
        out[f"policy seed {seed}, prior {HEADLINE:g}"] = at_headline(folder)
    out[f"policy, no corrector, prior {HEADLINE:g}"] = (
        learned + LOOP + prior(HEADLINE),
        policy / f"twin_underside_prior{HEADLINE:g}",
        HEADLINE,
    )
    for tag, matched in (("axis", []), ("underside", ["--matched", "underside"])):
        out[f"policy, look-ahead QP, {tag}, prior {HEADLINE:g}"] = (
            learned + matched + CORRECTOR + prior(HEADLINE),
            policy / f"lookahead_{tag}_corrector_prior{HEADLINE:g}",
            HEADLINE,
        )
    surface = Path("experiments/proxy/surface/multigait-joint_calibration.json")
    out[f"sequence, surface proxy, prior {HEADLINE:g}"] = (
        ["--proxy", str(surface), *LOOP, *CORRECTOR, *prior(HEADLINE)],
        RESULTS / f"surface_twin_underside_corrector_prior{HEADLINE:g}",
        HEADLINE,
    )
    for name in ("rl_multigait", "rl_multigait_points"):  # PPO on the node-ball proxy
        out[f"{name}, prior {HEADLINE:g}"] = at_headline(RESULTS / name)
    for level in LEVELS:
        for draw in DRAWS:
            folder = RESULTS / f"rl_multigait_surface_noise{level}_draw{draw}"
            out[f"robustness {level} draw {draw}, prior {HEADLINE:g}"] = at_headline(folder)
    return out


#: the same transfers without the prior (weight 0, experiments/proxy/twin.py) and open loop
#: with the corrector (experiments/proxy/corrector.py), read for comparison where they exist
def references() -> dict[str, Path]:
    out = {
        "sequence, prior 0": RESULTS / "twin_underside_corrector",
        "policy, prior 0": RESULTS / "rl_multigait_surface/twin_underside_corrector",
        "policy, open loop": RESULTS / "corrector/surface/gain0.5",
        "sequence, open loop": RESULTS / "feedforward",
    }
    for seed in SEEDS:
        folder = RESULTS / f"rl_multigait_surface_seed{seed}"
        out[f"policy seed {seed}, prior 0"] = folder / "twin_underside_corrector"
    return out


def row(name: str, folder: Path, weight: float | None, options: list[str]) -> dict | None:
    found = transfer_row(name, folder, options)
    return None if found is None else {"case": name, "prior_weight": weight, **found}


def bars(axes, names: list[str], series: list[tuple[str, str, list]]) -> None:
    """Grouped bars of FEM / proxy travel (%), cut at 200 % with the value written on top."""
    width = 0.8 / len(series)
    for k, (label, colour, values) in enumerate(series):
        x = [i + width * (k + 0.5) - 0.4 for i in range(len(names))]
        heights = [100 * v["fem_over_proxy"] if v else 0.0 for v in values]
        axes.bar(x, [min(h, 200.0) for h in heights], width, color=colour, label=label)
        for xi, h in zip(x, heights, strict=True):
            if h > 200.0:
                axes.text(xi, 190.0, f"{h:.0f}", ha="center", va="top", fontsize=6, rotation=90)
    axes.axhspan(95.0, 105.0, color="0.85", zorder=0)
    axes.set_ylim(-20.0, 200.0)
    axes.set_ylabel("FEM travel / proxy travel (%)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    run_transfers([(options, folder) for options, folder, _ in cases().values()], args.workers)

    rows = [row(name, folder, w, options) for name, (options, folder, w) in cases().items()]
    rows += [row(name, folder, None, []) for name, folder in references().items()]
    rows = [r for r in rows if r is not None]
    corrector = RESULTS / "corrector/corrector.json"
    if corrector.exists():  # the robustness policies' open loop with the corrector at 0.5
        for r in json.loads(corrector.read_text())["rows"]:
            if r["angle_gain"] == 0.5 and r["case"].startswith("surface_noise"):
                level, draw = r["case"][len("surface_noise") :].split("_draw")
                rows.append(
                    {
                        "case": f"robustness {level} draw {draw}, open loop",
                        "prior_weight": None,
                        "folder": str(corrector),
                        "actions": r["actions"],
                        "proxy_travel_mm": r["proxy_travel_mm"],
                        "fem_travel_mm": r["fem_travel_mm"],
                        "fem_over_proxy": round(r["fem_travel_mm"] / r["proxy_travel_mm"], 4),
                        "relative_difference": r["relative_difference"],
                    }
                )
    for r in rows:
        tracking = r.get("tracking_mean_mm")
        print(
            f"{r['case']}: proxy {r['proxy_travel_mm']:.2f} FEM {r['fem_travel_mm']:.2f} mm"
            + ("" if tracking is None else f", tracking {tracking:.2f} mm")
        )
    summary = {"command": "python experiments/proxy/prior.py " + " ".join(sys.argv[1:])}
    summary["rows"] = rows
    write_json(RESULTS / "prior_summary.json", summary)

    by = {r["case"]: r for r in rows}
    fig, (left, right, third) = plt.subplots(1, 3, figsize=(17, 4.5))
    for kind, colour in (("sequence", "C0"), ("policy", "C1")):
        found = [(0.0, by.get(f"{kind}, prior 0"))]
        found += [(w, by.get(f"{kind}, prior {w:g}")) for w in WEIGHTS]
        found = [(w, r) for w, r in found if r is not None]
        x = [max(w, 0.03) for w, _ in found]  # weight 0 drawn at the axis' left end
        label = "thesis' test sequence" if kind == "sequence" else "learned policy"
        left.plot(x, [100 * r["fem_over_proxy"] for _, r in found], "o-", color=colour, label=label)
        left.plot(
            x, [100 * r["tracking_mean_mm"] for _, r in found], "x:", color=colour,
            label=f"{label}: tracking error (mm, x100)",
        )  # fmt: skip
    left.axhspan(95.0, 105.0, color="0.85", label="within 5 %", zorder=0)
    left.set_xscale("log")
    left.set_xlabel("prior weight (0 drawn at 0.03)")
    left.set_ylabel("FEM travel / proxy travel (%)")
    left.legend(fontsize=7)
    names = ["policy"] + [f"policy seed {s}" for s in SEEDS]
    bars(
        right,
        names,
        [
            (suffix, colour, [by.get(f"{n}, {suffix}") for n in names])
            for suffix, colour in (("prior 0", "C0"), (f"prior {HEADLINE:g}", "C1"))
        ],
    )
    right.set_xticks(range(len(names)), ["seed 0"] + [f"seed {s}" for s in SEEDS])
    right.set_title("PPO's eight policies, twin, underside, corrector 0.5")
    right.legend(fontsize=7)
    names = [f"robustness {level} draw {d}" for level in LEVELS for d in DRAWS]
    bars(
        third,
        names,
        [
            (suffix, colour, [by.get(f"{n}, {suffix}") for n in names])
            for suffix, colour in (("open loop", "C2"), (f"prior {HEADLINE:g}", "C1"))
        ],
    )
    third.set_xticks(range(len(names)), [n[len("robustness ") :] for n in names], rotation=60)
    third.tick_params(axis="x", labelsize=7)
    third.set_title("robustness policies (noise, draw), corrector 0.5")
    third.legend(fontsize=7)
    fig.tight_layout()
    save_figure(fig, RESULTS / "prior_summary.png", dpi=110)


if __name__ == "__main__":
    main()
