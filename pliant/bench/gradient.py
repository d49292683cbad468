"""``pliant bench --gradient``: what a rollout gradient costs beside the rollout."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from rich.console import Console
from rich.table import Table

from pliant import robots
from pliant.bench.host import host


def report_gradient(*, quick: bool, out: Path, console: Console, repeats: int = 3) -> dict:
    """`pliant bench --gradient`: a rollout gradient's cost against its rollout
    (:func:`pliant.diff.cost.gradient_cost`) on the coarse Finger and the Diamond, each timed
    `repeats` times interleaved in this one process, medians (the ratio holds on a loaded
    machine better than either time)."""
    from pliant.diff.cost import gradient_cost
    from pliant.files import write_json

    cases = {"finger": (robots.soft_finger(), np.array([8.0, 0.0]), 20 if quick else 50)}
    if not quick:
        cases["diamond"] = (robots.diamond(), np.array([10.0, 0.0, 5.0, 0.0]), 30)
    rows = {name: gradient_cost(m, c, n, repeats=repeats) for name, (m, c, n) in cases.items()}
    table = Table(
        title=f"a rollout's gradient (controls, E, nu) against the rollout, medians of {repeats}"
    )
    for col in ("scene", "steps", "forward s", "gradient s", "ratio", "checkpointed ratio"):
        table.add_column(col, justify="right")
    for name, r in rows.items():
        table.add_row(
            name,
            str(r["steps"]),
            f"{r['forward_s']:.2f}",
            f"{r['all_states_kept']['gradient_s']:.2f}",
            f"{r['all_states_kept']['gradient_over_forward']:.1f}x",
            f"{r['checkpoints_sqrt_T']['gradient_over_forward']:.1f}x",
        )
    console.print(table)
    write_json(out, {"gradient": rows, "quick": quick, "repeats": repeats, "host": host()})
    console.print(f"saved {out}")
    return rows
