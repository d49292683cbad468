"""Session 32's Trunk comparison gathered from its reports (docs/proxy.md, "PPO's exploration"):
PPO with log_std_init -1 on the shortening-beam proxy (its bendings, then the FEM's cables as
actions) and directly on the FEM, five seeds, the same 20 goals; the FEM policies also played
on the proxy (experiments/proxy/fem_policy_on_proxy.py). Reads the reports the commands in
docs/proxy.md wrote; writes experiments/results/proxy/fem_vs_proxy/exploration_summary.json.

    python experiments/proxy/exploration_summary.py
"""

from __future__ import annotations

import json

import numpy as np
from scipy.stats import wilcoxon

from pliant.transfer.reports import FEM, PROXY, SEEDS, fem_side, mean, proxy_side, seeded


def main() -> None:
    fem = fem_side("_std1")
    out = {"ppo_on_fem": {"seeds": fem}}
    out["ppo_on_fem"].update(
        {k: mean(fem, k) for k in ("on_fem_mm", "on_fem_solved", "on_proxy_mm")}
    )
    for label, tag in (("bendings", "_contraction_std1"), ("cables", "_contraction_cables")):
        rows = proxy_side(tag)
        pipeline = np.array([r["on_fem_mm"] for r in rows])
        direct = np.array([r["on_fem_mm"] for r in fem])
        out[f"pipeline_{label}"] = {
            "seeds": rows,
            **{k: mean(rows, k) for k in ("on_proxy_mm", "on_proxy_solved", "on_fem_mm")},
            "on_fem_solved": mean(rows, "on_fem_solved"),
            "wins_over_ppo_on_fem": int(np.sum(pipeline < direct)),
            "wilcoxon_p_two_sided": float(wilcoxon(pipeline, direct).pvalue),
        }
    # The 2 x 2 on the proxy alone: the action space, crossed with SB3's default initial std
    # (log_std_init 0: session 31's bendings runs, and the cables without the change).
    crossed = {}
    for label, tag in (
        ("bendings_std1", "_contraction_nolag"),
        ("bendings_std0.37", "_contraction_std1"),
        ("cables_std1", "_contraction_cables_std0"),
        ("cables_std0.37", "_contraction_cables"),
    ):
        learned = [
            json.loads((PROXY / seeded(f"rl_trunk{tag}", s) / "report.json").read_text())[
                "evaluation"
            ]["learned"]
            for s in SEEDS
        ]
        crossed[label] = {
            "on_proxy_mm": [r["mean_final_distance_mm"] for r in learned],
            "mean_on_proxy_mm": float(np.mean([r["mean_final_distance_mm"] for r in learned])),
            "mean_solved": float(np.mean([r["solved"] for r in learned])),
        }
    out["on_the_proxy_by_action_space_and_initial_std"] = crossed
    out["settings"] = {
        "hyperparams_over_proxy_rl_settings": {"policy_kwargs": {"log_std_init": -1.0}},
        "proxy": "experiments/proxy/contraction/trunk_calibration.json (beams that shorten)",
        "budget": "6800 environment steps of 0.3 s = 2.04e5 simulation steps a run",
        "goals": "seeds 1000-1019 of both environments",
    }
    (FEM / "exploration_summary.json").write_text(json.dumps(out, indent=1))
    for key in ("ppo_on_fem", "pipeline_bendings", "pipeline_cables"):
        print(key, {k: v for k, v in out[key].items() if k != "seeds"})
    for key, row in crossed.items():
        print(key, row)


if __name__ == "__main__":
    main()
