"""Sessions 34-35's Trunk comparison (docs/proxy.md, "The proxy at its own time step"): the
pipeline on the axial proxy (cube fitted on the FEM's pushes, the FEM's cables as actions,
log_std_init -1) against PPO directly on the FEM, five or ten seeds a side (SIDES,
PIPELINES), at two budgets:

* 2.04e5 simulation steps, the thesis' budget: PPO on the FEM takes 6800 environment steps
  of 30 x 0.01 s; the pipeline either as many on the proxy at the FEM's 0.01 s, or 20400 on
  the proxy at 0.03 s (10 sub-steps a 0.3 s step; experiments/proxy/timestep.py measured it
  replays the FEM's pushes as well as at 0.01 s);
* 20400 environment steps (three times the above): PPO on the FEM (6.1e5 simulation steps)
  against the pipeline on the proxy at 0.01 s (6.1e5) and at 0.03 s (2.04e5);
* the control: PPO on the FEM itself stepped at 0.03 s (20400 environment steps, 2.04e5
  simulation steps; experiments/proxy/timestep.py measured its cube as near the 0.01 s
  FEM's as the proxy's), evaluated on the FEM at 0.01 s, against the pipeline at 0.03 s;
  its cables either at the Trunk's 1 mm a simulation step (a third of their speed at
  0.01 s) or at 3 mm (`proxy/vs_fem_rl.py --fem-cable-step 3`: as fast as at 0.01 s).

Each row pairs the seeds (the same PPO seed on both sides): the mean final cube-goal
distance on the FEM over the 20 evaluation goals, the share solved (< 8 mm), the seeds on
which the pipeline ends nearer than PPO on the FEM, a two-sided Wilcoxon signed-rank p, and
the training wall times, on the seeds both sides have. It only reads the reports the
commands in docs/proxy.md wrote; the seeds not run yet are listed as missing.

    python experiments/proxy/timestep_summary.py

Writes experiments/results/proxy/fem_vs_proxy/timestep_summary.json.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import numpy as np
from scipy.stats import wilcoxon

from pliant.transfer.reports import FEM, PROXY, fem_side, mean, proxy_side, seeded

#: PPO on the FEM: label -> (run tag, simulation steps, seeds run)
SIDES = {
    "ppo_on_fem_2e5": ("_std1", 6800 * 30, range(10)),
    "ppo_on_fem_6e5": ("_std1_3x", 20400 * 30, range(5)),
    # the control: PPO on the FEM stepped at 0.03 s (evaluated at 0.01 s like every policy),
    # its cables at the Trunk's 1 mm a simulation step (a third of their speed at 0.01 s) ...
    "ppo_on_fem_dt003_20400": ("_std1_dt03", 20400 * 10, range(5)),
    # ... and at 3 mm a step (as fast as at 0.01 s, where every policy is evaluated)
    "ppo_on_fem_dt003_cable3_20400": ("_std1_dt03_cable3", 20400 * 10, range(10)),
}
#: the pipeline: label -> (proxy run tag, the proxy's simulation steps, seeds run)
PIPELINES = {
    "proxy_dt001_6800": ("_axial_cables", 6800 * 30, range(5)),
    "proxy_dt001_20400": ("_axial_cables_3x", 20400 * 30, range(5)),
    "proxy_dt003_20400": ("_axial_cables_dt03", 20400 * 10, range(10)),
}
#: the comparisons: (pipeline, PPO on the FEM)
PAIRS = (
    ("proxy_dt001_6800", "ppo_on_fem_2e5"),  # equal simulation steps, the thesis' budget
    ("proxy_dt003_20400", "ppo_on_fem_2e5"),  # equal simulation steps, the proxy's own dt
    ("proxy_dt001_20400", "ppo_on_fem_6e5"),  # equal environment steps, three times
    ("proxy_dt003_20400", "ppo_on_fem_6e5"),
    ("proxy_dt003_20400", "ppo_on_fem_dt003_20400"),  # both models at 0.03 s
    ("proxy_dt003_20400", "ppo_on_fem_dt003_cable3_20400"),
)


def run_seeds(report: Callable[[int], Path], seeds: range) -> tuple[list[int], list[int]]:
    """The seeds among `seeds` whose report (the path `report` gives for a seed) exists, and
    those missing (a run not done yet: the summary lists them rather than failing)."""
    done = [s for s in seeds if report(s).exists()]
    return done, [s for s in seeds if s not in done]


def paired(rows: list[dict], seeds: list[int]) -> list[dict]:
    return [r for r in rows if r["seed"] in seeds]


def means(rows: list[dict], keys: tuple[str, ...]) -> dict:
    """The seeds' mean of each of `keys` (none for a side not run yet)."""
    return {k: mean(rows, k) for k in keys} if rows else {}


def compare(first: list[dict], second: list[dict], names=("pipeline", "ppo")) -> dict:
    """`first` against `second` (the pipeline against PPO on the FEM, by default) on the
    seeds both have: mean final distance on the FEM, the seeds on which `first` ends nearer,
    a two-sided Wilcoxon signed-rank p and the mean training wall times."""
    common = sorted({r["seed"] for r in first} & {r["seed"] for r in second})
    if not common:
        return {"seeds": [], "status": "not run yet"}
    a = np.array([r["on_fem_mm"] for r in paired(first, common)])
    b = np.array([r["on_fem_mm"] for r in paired(second, common)])
    one, two = names
    return {
        "seeds": common,
        f"{one}_on_fem_mm": float(a.mean()),
        f"{two}_on_fem_mm": float(b.mean()),
        f"{one}_wins": int(np.sum(a < b)),
        "wilcoxon_p_two_sided": float(wilcoxon(a, b).pvalue),
        f"{one}_training_seconds": mean(paired(first, common), "training_seconds"),
        f"{two}_training_seconds": mean(paired(second, common), "training_seconds"),
    }


def main() -> None:
    out: dict = {"sides": {}, "comparisons": []}
    rows = {}
    for label, (tag, simulation_steps, seeds) in SIDES.items():
        done, missing = run_seeds(
            lambda s, tag=tag: FEM / seeded(tag.lstrip("_"), s) / "report.json", seeds
        )
        rows[label] = fem_side(tag, seeds=done)
        out["sides"][label] = {
            "tag": tag,
            "simulation_steps": simulation_steps,
            "missing_seeds": missing,
            "seeds": rows[label],
            **means(rows[label], ("on_fem_mm", "on_fem_solved")),
        }
    for label, (tag, simulation_steps, seeds) in PIPELINES.items():
        done, missing = run_seeds(
            lambda s, tag=tag: FEM / f"report_{seeded(f'rl_trunk{tag}', s)}.json", seeds
        )
        rows[label] = proxy_side(tag, seeds=done)
        out["sides"][label] = {
            "tag": tag,
            "proxy_simulation_steps": simulation_steps,
            "missing_seeds": missing,
            # the inverse QP's build in the transfers: the baseline is reproducible, the
            # vectorised builds (every transfer before session 36) are not (docs/proxy.md)
            "proxsuite_builds": sorted({r["proxsuite_build"] for r in rows[label]}),
            "seeds": rows[label],
            **means(rows[label], ("on_proxy_mm", "on_proxy_solved", "on_fem_mm", "on_fem_solved")),
        }
    for pipeline, direct in PAIRS:
        out["comparisons"].append(
            {"pipeline": pipeline, "direct": direct, **compare(rows[pipeline], rows[direct])}
        )
    # not the pipeline: the coarse step alone, PPO on the FEM at 0.03 s (cables at full
    # speed) against PPO on the FEM at 0.01 s, both 2.04e5 simulation steps
    out["fem_at_003_against_fem_at_001"] = compare(
        rows["ppo_on_fem_dt003_cable3_20400"], rows["ppo_on_fem_2e5"], ("fem_003", "fem_001")
    )
    out["replay_by_time_step"] = json.loads((PROXY / "timestep.json").read_text())
    (FEM / "timestep_summary.json").write_text(json.dumps(out, indent=1))
    for label, side in out["sides"].items():
        print(label, {k: v for k, v in side.items() if k not in ("seeds", "tag")})
    for row in out["comparisons"]:
        print(row)
    print("FEM at 0.03 s against 0.01 s:", out["fem_at_003_against_fem_at_001"])


if __name__ == "__main__":
    main()
