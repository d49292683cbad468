"""Learned against exact condensed matrices along the thesis trajectories (Fig. 5.4, Table 5.8
analogue): the Diamond circle of 30 goals and the Finger closing trajectory of 25 goals, open
loop and with the PID goal correction of Eq. 5.14; plots and errors.

Needs the models of table_5_1.py:

    OPENBLAS_NUM_THREADS=1 python experiments/condensed/trajectories.py \
        out/condensed_full/finger_6500.pt out/condensed_full/diamond_6500.pt

The Diamond's circle (`lifted_circle`, radius 15 mm at z = 140 mm) lies in the workspace of
the learned box (cables pulled 0-30 mm): pulling the cables raises the effector from z = 125 mm
(the elbows are drawn down and in); the robot's `circle` at z = 115 mm needs cables paying out
below their rest length, which the box excludes.

Each goal gets --iterations control iterations on the FEM robot (the plant), with W and
delta_free from the network or from the FEM. The error of Table 5.8 is |d_exact - d_learned| /
d_exact, d the mean effector-goal distance over the trajectory; the gap is the mean distance
between the positions reached with learned and with exact matrices.
"""

from __future__ import annotations

import json
import warnings
from pathlib import Path
from typing import Annotated

import numpy as np
import typer

from pliant import robots
from pliant.condensed.control import PID, ExactCondensed, follow_trajectory
from pliant.condensed.learned import LearnedCondensedModel, OutOfBoundsWarning
from pliant.condensed.plots import plot_reached
from pliant.solvers import StaticSolver

GOALS = {"diamond": ("lifted_circle", 30, (0, 1)), "finger": ("closing", 25, (0, 2))}


def main(
    models: Annotated[list[Path], typer.Argument(help="learned model files")],
    iterations: Annotated[int, typer.Option()] = 5,
    pid: Annotated[str, typer.Option(help="K,I,D of the closed loop")] = "0.5,0.1,0",
    out: Annotated[Path, typer.Option(help="results")] = Path("experiments/results/condensed"),
) -> None:
    out.mkdir(parents=True, exist_ok=True)
    path = out / "trajectories.json"
    # Robots run separately update their own rows of the report.
    report = json.loads(path.read_text()) if path.is_file() else {}
    for model in models:
        learned = LearnedCondensedModel.load(model)
        robot = learned.plan.robot
        name, n, plane = GOALS[robot]
        goals = robots.entry(robot).trajectories[name](n)
        fem = robots.build(robot, **learned.plan.robot_kwargs)
        rows = {"model": model.name, "training_samples": learned.plan.n_train}
        for loop, gains in (("open", None), ("closed", [float(v) for v in pid.split(",")])):
            reached = {}
            for source_name, source in (
                ("learned", learned),
                # The reference is the W the network learned (the plan's tangent).
                (
                    "exact",
                    ExactCondensed(
                        fem, StaticSolver(fem, consistent=learned.plan.consistent_tangent)
                    ),
                ),
            ):
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore", OutOfBoundsWarning)
                    reached[source_name] = follow_trajectory(
                        fem,
                        goals,
                        source,
                        iterations=iterations,
                        pid=PID(*gains) if gains else None,
                        course=learned.input_box,
                    )
            d = {k: float(r.errors.mean()) for k, r in reached.items()}
            gap = np.linalg.norm(reached["learned"].reached - reached["exact"].reached, axis=-1)
            rows[loop] = {
                "mean_distance_to_goal": d,
                "table_5_8_error": abs(d["exact"] - d["learned"]) / d["exact"],
                "learned_vs_exact_gap_mean": float(gap.mean()),
                "learned_vs_exact_gap_max": float(gap.max()),
            }
            plot_reached(
                goals,
                {k: r.reached[:, 0] for k, r in reached.items()},
                out / f"trajectory_{robot}_{name}_{loop}.png",
                plane=plane,
                title=f"{robot} {name}, {loop} loop: learned vs exact",
            )
            print(robot, loop, json.dumps(rows[loop]))
        report[f"{robot}_{name}"] = rows
    report["settings"] = {"iterations_per_goal": iterations, "pid": pid, "units": "mm"}
    report["note"] = (
        "The Diamond follows lifted_circle (radius 15 mm at z = 140 mm), in the workspace of"
        " the learned box (cables 0-30 mm): pulling the cables raises the effector from z ="
        " 125 mm; the circle below it (z = 115 mm) needs cables paying out below their rest"
        " length."
    )
    path.write_text(json.dumps(report, indent=1))


if __name__ == "__main__":
    typer.run(main)
