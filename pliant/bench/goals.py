"""Issue #62's speed goals, read from what ``pliant bench`` measured (``pliant bench --goals``).

Each goal is checked on the result files of one results folder (``bench.json``, ``envs.json``,
``learner_training.json``: whichever are there), never on figures typed in: a goal whose
measurement is absent is listed as not measured. The goals:

- the default step at least 10x SOFA's steps/s on every scene with a SOFA figure (SPEC §5's, or
  SOFA's own scene loaded), and the exact step (the faster of ``fresh`` and ``pcg``) at least 5x;
- Pliant at least 3x MuJoCo flex (converged) on the same cantilevers, in the same run;
- every environment at least 10x real time at dt = 0.01, the full Multigait at least 2x;
- SAC on CartStemContact: training steps/s (updates included) at least 3x SB3's own updates.

Where a goal is missed, :data:`BREAKDOWN` names where the measured breakdown and what was tried
are written (docs/concepts/speed.md's sections and the JSON beside the figure).
"""

from __future__ import annotations

import json
from pathlib import Path

from rich.console import Console
from rich.table import Table

from pliant.errors import CorruptFileError
from pliant.files import write_json

DEFAULT_VS_SOFA = 10.0
EXACT_VS_SOFA = 5.0
VS_MUJOCO = 3.0
REAL_TIME = 10.0
MULTIGAIT_REAL_TIME = 2.0
SAC_TRAINING = 3.0

BREAKDOWN = {
    "sofa": "bench.json: each row's breakdown_lagged (forces, assembly, factorisation, solves,"
    " constraints, rest); docs/concepts/speed.md, 'No refactorisation' and 'The element pass'",
    "mujoco": "bench.json: mujoco_flex_peer; docs/concepts/speed.md, 'Against MuJoCo flex'",
    "env": "env_profile.json (pliant bench --envs ... --env-profile);"
    " docs/studies/environment-speed.md",
    "sac": "learner_training.json, learner.json; docs/concepts/speed.md, 'The learner'",
}


def _load(path: Path) -> dict | None:
    if not path.exists():
        return None
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError) as error:
        raise CorruptFileError(f"{path}: not a readable bench result ({error})") from error


def _row(
    goal: str, subject: str, measured: float | None, target: float, kind: str, note: str = ""
) -> dict:
    met = None if measured is None else bool(measured >= target)
    return {
        "goal": goal,
        "subject": subject,
        "measured": measured,
        "target": target,
        "met": met,
        "note": note,
        "breakdown": None if met else BREAKDOWN[kind],
    }


def sofa_goals(bench: dict) -> list[dict]:
    """Default / SOFA >= 10 and exact / SOFA >= 5 on every scene with a SOFA figure."""
    scenes: dict[str, dict[str, float]] = {}
    for r in bench.get("scenes", []):
        if r.get("sofa") and r.get("steps_per_s"):
            scenes.setdefault(r["scene"], {})[r["policy"]] = r["steps_per_s"] / r["sofa"]
    rows = []
    for scene, ratios in scenes.items():
        if "lagged" in ratios:
            rows.append(
                _row("default step / SOFA", scene, ratios["lagged"], DEFAULT_VS_SOFA, "sofa")
            )
        exact = [ratios[p] for p in ("fresh", "pcg") if p in ratios]
        if exact:
            rows.append(_row("exact step / SOFA", scene, max(exact), EXACT_VS_SOFA, "sofa"))
    return rows


def mujoco_goals(bench: dict) -> list[dict]:
    """Pliant / MuJoCo flex (converged) >= 3 at every size raced."""
    peer = bench.get("mujoco_flex_peer") or {}
    rows = []
    for r in peer.get("rows", []):
        ratio = (r.get("mujoco") or {}).get("converged", {}).get("ratio")
        rows.append(_row("Pliant / MuJoCo flex", r["scene"], ratio, VS_MUJOCO, "mujoco"))
    return rows


def env_goals(envs: dict) -> list[dict]:
    """Real-time factor at dt = 0.01 >= 10 (the full Multigait >= 2)."""
    rows = []
    for r in envs.get("environments", []):
        if abs(r.get("dt", 0.0) - 0.01) > 1e-12:
            continue
        target = MULTIGAIT_REAL_TIME if r["env"] == "Multigait" else REAL_TIME
        stable = r.get("stable", True) and "real_time_factor" in r
        measured = r["real_time_factor"] if stable else None
        note = "" if stable else (r.get("note") or "not stable at dt 0.01")
        rows.append(_row("real-time factor at dt 0.01", r["env"], measured, target, "env", note))
    return rows


def sac_goal(training: dict) -> list[dict]:
    """SAC CartStemContact's training steps/s with Pliant's updates against SB3's, >= 3."""
    runs = [r for r in training.get("training", []) if r.get("algo") == "SAC"]
    rate = {r["fast_updates"]: r["cpu_bound_steps_per_s"] for r in runs}
    measured = rate[True] / rate[False] if True in rate and False in rate else None
    return [_row("SAC training steps/s vs SB3's", "CartStemContact", measured, SAC_TRAINING, "sac")]


def goal_rows(folder: Path) -> list[dict]:
    """Every goal that the result files in `folder` measure."""
    rows: list[dict] = []
    bench = _load(folder / "bench.json")
    if bench is not None:
        rows += sofa_goals(bench) + mujoco_goals(bench)
    envs = _load(folder / "envs.json")
    if envs is not None:
        rows += env_goals(envs)
    training = _load(folder / "learner_training.json")
    if training is not None:
        rows += sac_goal(training)
    return rows


def report_goals(folder: Path, *, console: Console, out: Path | None = None) -> list[dict]:
    """Print the goals met and missed from `folder`'s results and write ``goals.json``."""
    rows = goal_rows(folder)
    if not rows:
        raise FileNotFoundError(
            f"{folder}: no bench.json, envs.json or learner_training.json to read goals from"
        )
    table = Table(title=f"#62's goals, from {folder}")
    for col in ("goal", "subject", "measured", "target", "met"):
        table.add_column(col)
    for r in rows:
        shown = (
            r["note"][:40] or "not measured" if r["measured"] is None else f"{r['measured']:.2f}x"
        )
        met = {True: "yes", False: "no", None: "-"}[r["met"]]
        table.add_row(r["goal"], r["subject"], shown, f">= {r['target']:g}x", met)
    console.print(table)
    missed = sorted({r["breakdown"] for r in rows if r["met"] is False})
    for where in missed:
        console.print(f"missed: breakdown in {where}")
    target = out or folder / "goals.json"
    write_json(target, {"folder": str(folder), "goals": rows})
    return rows
