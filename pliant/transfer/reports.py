"""The Trunk transfer studies' reports gathered into rows (experiments/proxy/exploration_summary.py,
push_summary.py, timestep_summary.py, robustness.py): each seed's proxy policy on its proxy and
transferred to the FEM, PPO's on the FEM, and a Multigait transfer's summary row
(experiments/proxy/corrector.py, prior.py, twin.py). They read the result files the studies
wrote, relative to the working directory.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

PROXY = Path("experiments/results/proxy")
FEM = PROXY / "fem_vs_proxy"
SEEDS = range(5)


def seeded(name: str, seed: int) -> str:
    """A run's folder name for `seed` (seed 0's has no suffix)."""
    return name if seed == 0 else f"{name}_seed{seed}"


def transferred(name: str, seed: int) -> dict:
    """The FEM's summary of proxy policy `name` transferred: its own report (--transfer-only),
    or the pipeline half of the run that trained PPO on the FEM beside it."""
    alone = FEM / f"report_{name}.json"
    if alone.exists():
        return json.loads(alone.read_text())
    both = json.loads((FEM / seeded("std1", seed) / "report.json").read_text())["proxy_pipeline"]
    if Path(both["policy"]).name != name:
        raise FileNotFoundError(f"no transfer of {name} found in {FEM}")
    return both


#: the ProxQP build of the transfers whose reports do not say (before session 36, this machine)
EARLIER_BUILD = "proxsuite_pywrap_avx512"


def proxy_side(tag: str, seeds=SEEDS) -> list[dict]:
    """Each seed's policy on its proxy (:func:`pliant.transfer.rl.evaluate`) and transferred to
    the FEM (with the inverse QP's ProxQP build of the transfer)."""
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
    """Each seed's PPO on the FEM, and (where proxy/fem_policy_on_proxy.py wrote
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
    """The mean of `key` over `rows`."""
    return float(np.mean([r[key] for r in rows]))


def transfer_row(name: str, folder: Path, options: list[str]) -> dict | None:
    """The summary of the transfer in `folder` (None, with a line on stderr, if it is not
    there): its actions, both travels, their ratio and relative difference, the matched
    points' mean distance at each step's end (tracking), each step's travels, the twin's
    resets and the inverse steps that failed."""
    path = Path(folder) / "multigait_transfer.json"
    if not path.exists():
        print(f"missing: {path}", file=sys.stderr)
        return None
    report = json.loads(path.read_text())
    steps = report["steps"]
    proxy, fem = report["proxy_return"], report["fem_return"]
    tracking = [s["tracking_error"] for s in steps]
    return {
        "case": name,
        "options": options,
        "folder": str(folder),
        "actions": [s["action"] for s in steps],
        "proxy_travel_mm": round(proxy, 3),
        "fem_travel_mm": round(fem, 3),
        "fem_over_proxy": round(fem / proxy, 4) if proxy else None,
        "relative_difference": round(abs(proxy - fem) / abs(fem), 4) if fem else None,
        "tracking_mean_mm": round(float(np.mean(tracking)), 3),
        "tracking_mm": [round(t, 3) for t in tracking],
        "proxy_steps_mm": [round(s["proxy_reward"], 3) for s in steps],
        "fem_steps_mm": [round(s["fem_reward"], 3) for s in steps],
        "twin_resets": report.get("twin_resets", 0),
        "failed_inverse_steps": report["failed_inverse_steps"],
        "wall_time_s": round(report["wall_time_s"], 1),
    }
