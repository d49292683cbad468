"""Session 32's Trunk comparison gathered from its reports (docs/proxy.md, "PPO's exploration"):
PPO with log_std_init -1 on the shortening-beam proxy (its bendings, then the FEM's cables as
actions) and directly on the FEM, five seeds, the same 20 goals; the FEM policies also played
on the proxy (experiments/proxy_fem_policy_on_proxy.py). Reads the reports the commands in
docs/proxy.md wrote; writes experiments/results/proxy/fem_vs_proxy/exploration_summary.json.

    python experiments/proxy_exploration_summary.py
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from scipy.stats import wilcoxon

PROXY = Path("experiments/results/proxy")
FEM = PROXY / "fem_vs_proxy"
SEEDS = range(5)


def seeded(name: str, seed: int) -> str:
    return name if seed == 0 else f"{name}_seed{seed}"


def transferred(name: str, seed: int) -> dict:
    """The FEM's summary of proxy policy `name` transferred: its own report (--transfer-only),
    or the pipeline half of the run that trained PPO on the FEM beside it."""
    alone = FEM / f"report_{name}.json"
    if alone.exists():
        return json.loads(alone.read_text())
    both = json.loads((FEM / seeded("std1", seed) / "report.json").read_text())["proxy_pipeline"]
    if Path(both["policy"]).name != name:
        raise SystemExit(f"no transfer of {name} found")
    return both


#: the ProxQP build of the transfers whose reports do not say (before session 36, this machine)
EARLIER_BUILD = "proxsuite_pywrap_avx512"


def proxy_side(tag: str, seeds=SEEDS) -> list[dict]:
    """Each seed's policy on its proxy (proxy_rl.py's evaluation) and transferred to the FEM
    (with the inverse QP's ProxQP build of the transfer)."""
    rows = []
    for s in seeds:
        name = seeded(f"rl_trunk{tag}", s)
        own = json.loads((PROXY / name / "report.json").read_text())
        moved = transferred(name, s)
        learned = own["evaluation"]["learned"]
        rows.append(
            {
                "seed": s,
                "on_proxy_mm": learned["mean_final_distance_mm"],
                "on_proxy_solved": learned["solved"],
                "on_fem_mm": moved["fem"]["mean_final_distance_mm"],
                "on_fem_solved": moved["fem"]["solved_under_8mm"],
                "training_seconds": own["training_seconds"],
                "proxsuite_build": moved.get("proxsuite_build", EARLIER_BUILD),
            }
        )
    return rows


def fem_side(tag: str, replay: str = "fitted", seeds=SEEDS) -> list[dict]:
    """Each seed's PPO on the FEM, and (where proxy_fem_policy_on_proxy.py wrote
    proxy_replay_REPLAY.json) the same policy played on a proxy."""
    rows = []
    for s in seeds:
        folder = FEM / seeded(tag.lstrip("_"), s)
        direct = json.loads((folder / "report.json").read_text())["rl_on_fem"]
        row = {
            "seed": s,
            "on_fem_mm": direct["mean_final_distance_mm"],
            "on_fem_solved": direct["solved_under_8mm"],
            "training_seconds": direct["training_seconds"],
        }
        played = folder / f"proxy_replay_{replay}.json"
        if played.exists():
            on_proxy = json.loads(played.read_text())["on_the_proxy"]
            row["on_proxy_mm"] = on_proxy["mean_final_distance_mm"]
            row["on_proxy_solved"] = on_proxy["solved_under_8mm"]
        rows.append(row)
    return rows


def mean(rows: list[dict], key: str) -> float:
    return float(np.mean([r[key] for r in rows]))


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
