"""Session 33's Trunk comparison (docs/proxy.md, "A proxy fitted on the FEM's pushes"): the
proxy's cube fitted on the FEM's pushes, then the proxy's axial commands (cables pulled
together) with the cube fitted again; on each, the pipeline's five seeds (the FEM's cables as
actions, log_std_init -1) against PPO on the FEM (the same five seeds as session 32's); then
seeds 0 and 1 of both with three times the steps.

Besides the reports the commands in docs/proxy.md wrote, it measures one thing itself: the
five FEM policies' greedy episodes on the 20 evaluation goals (seeds 1000-1019, which none of
the calibrations saw), replayed open loop on each proxy (:mod:`pliant.transfer.pushes`): how far
the proxy's cube is from the FEM's along them, and where it ends. About 3 minutes.

    python experiments/proxy/push_summary.py

Writes experiments/results/proxy/fem_vs_proxy/push_summary.json.
"""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np
from scipy.stats import wilcoxon

from pliant.envs.trunk_push_proxy import TrunkPushProxyEnv
from pliant.learn.evaluate import load_policy
from pliant.transfer.fem_rl import FEM_KWARGS, GOALS
from pliant.transfer.pushes import fem_pushes, proxy_pushes
from pliant.transfer.reports import FEM, fem_side, mean, proxy_side, seeded
from pliant.transfer.rl import SETTINGS

#: the proxies compared: (label, calibration report, pipeline tag, FEM-policy replay name)
PROXIES = (
    ("shortening beams", "experiments/proxy/contraction/trunk_calibration.json",
     "_contraction_cables", "fitted"),
    ("+ cube fitted on pushes", "experiments/proxy/push/trunk-push_calibration.json",
     "_push_cables", "push"),
    ("+ axial commands, cube fitted again",
     "experiments/proxy/push_cocontraction/trunk-push_calibration.json", "_axial_cables",
     "axial"),
)  # fmt: skip


def parameters(report: str) -> dict:
    return json.loads(Path(report).read_text())["parameters"]


def open_loop() -> dict:
    """The FEM policies' episodes on the evaluation goals, replayed on each proxy."""
    env = TrunkPushProxyEnv(**SETTINGS["trunk"]["env_kwargs"])
    goals = []
    for s in GOALS:
        env.reset(seed=s)
        goals.append(env.task["goal"][[0, 2]])
    goals = np.array(goals)

    def final(cubes: np.ndarray) -> np.ndarray:
        return np.hypot(*(cubes[:, -1, [0, 2]] - goals).T)

    rows = []
    for s in range(5):
        saved = load_policy(FEM / seeded("std1", s))

        def greedy(obs, rng, saved=saved):
            return saved.model.predict(saved.normalize_obs(obs), deterministic=True)[0]

        fem = fem_pushes(greedy, len(GOALS), seed=GOALS[0], env_kwargs=FEM_KWARGS)
        row = {"seed": s, "fem_final_distance_mm": float(final(fem.cubes).mean())}
        for label, report, _, _ in PROXIES:
            kwargs = {**SETTINGS["trunk"]["env_kwargs"], **parameters(report)}
            cubes = proxy_pushes(fem, kwargs)
            row[label] = {
                "cube_error_mm": float(np.linalg.norm(cubes - fem.cubes, axis=-1).mean()),
                "final_distance_mm": float(final(cubes).mean()),
            }
        rows.append(row)
        print("open loop", row)
    summary = {"fem_final_distance_mm": mean(rows, "fem_final_distance_mm")}
    for label, *_ in PROXIES:
        summary[label] = {
            key: float(np.mean([r[label][key] for r in rows]))
            for key in ("cube_error_mm", "final_distance_mm")
        }
    return {"policies": rows, "mean": summary}


def three_times() -> list[dict]:
    """Seeds 0 and 1 with 3 x 6800 environment steps (6.1e5 simulation steps) on both sides:
    the pipeline on the axial proxy, PPO on the FEM (fem_vs_proxy/std1_3x[_seedS])."""
    rows = []
    for s in range(2):
        proxy = json.loads(
            (FEM / f"report_{seeded('rl_trunk_axial_cables_3x', s)}.json").read_text()
        )
        fem = json.loads((FEM / seeded("std1_3x", s) / "report.json").read_text())["rl_on_fem"]
        rows.append(
            {
                "seed": s,
                "pipeline_on_proxy_mm": proxy["proxy"]["mean_final_distance_mm"],
                "pipeline_on_fem_mm": proxy["fem"]["mean_final_distance_mm"],
                "pipeline_solved_on_fem": proxy["fem"]["solved_under_8mm"],
                "pipeline_training_seconds": proxy["proxy_training_seconds"],
                "ppo_on_fem_mm": fem["mean_final_distance_mm"],
                "ppo_on_fem_solved": fem["solved_under_8mm"],
                "ppo_on_fem_training_seconds": fem["training_seconds"],
                "simulation_steps": fem["simulation_steps"],
            }
        )
    return rows


def main() -> None:
    warnings.simplefilter("ignore")
    out = {
        "calibrations": {
            "push": json.loads(Path(PROXIES[1][1]).read_text()),
            "axial": json.loads(
                Path(
                    "experiments/proxy/cocontraction/trunk-cocontraction_calibration.json"
                ).read_text()
            ),
            "push_on_axial": json.loads(Path(PROXIES[2][1]).read_text()),
        }
    }
    for calibration in out["calibrations"].values():  # the per-kind tables stay in the files
        calibration.pop("by_kind_before", None)
        calibration.pop("by_kind_after", None)
    direct = np.array([r["on_fem_mm"] for r in fem_side("_std1")])
    out["ppo_on_fem"] = {"on_fem_mm": direct.tolist(), "mean_on_fem_mm": float(direct.mean())}
    for label, report, tag, replay in PROXIES:
        rows = proxy_side(tag)
        pipeline = np.array([r["on_fem_mm"] for r in rows])
        played = fem_side("_std1", replay)
        out[label] = {
            "calibration": report,
            "pipeline": {
                "seeds": rows,
                **{k: mean(rows, k) for k in ("on_proxy_mm", "on_proxy_solved", "on_fem_mm")},
                "on_fem_solved": mean(rows, "on_fem_solved"),
                "wins_over_ppo_on_fem": int(np.sum(pipeline < direct)),
                "wilcoxon_p_two_sided": float(wilcoxon(pipeline, direct).pvalue),
            },
            "fem_policies_closed_loop_on_this_proxy_mm": [r["on_proxy_mm"] for r in played],
            "fem_policies_closed_loop_on_this_proxy_mean_mm": mean(played, "on_proxy_mm"),
        }
    out["three_times_the_steps"] = three_times()
    out["fem_policies_open_loop_on_the_proxies"] = open_loop()
    out["settings"] = {
        "pipeline": "proxy/rl.py trunk --cables --parameters REPORT, log_std_init -1; "
        "proxy/vs_fem_rl.py --transfer-only",
        "budget": "6800 environment steps of 0.3 s = 2.04e5 simulation steps a run",
        "goals": "seeds 1000-1019 of both environments",
    }
    (FEM / "push_summary.json").write_text(json.dumps(out, indent=1))
    for label, *_ in PROXIES:
        print(label, {k: v for k, v in out[label]["pipeline"].items() if k != "seeds"})
        print("  FEM policies on it:", out[label]["fem_policies_closed_loop_on_this_proxy_mean_mm"])
    print("open loop", out["fem_policies_open_loop_on_the_proxies"]["mean"])
    for row in out["three_times_the_steps"]:
        print("3x", row)


if __name__ == "__main__":
    main()
