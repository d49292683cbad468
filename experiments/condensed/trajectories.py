"""Learned against exact condensed matrices along the thesis trajectories (Fig. 5.4, Table 5.8
analogue): the Diamond circle of 30 goals and the Finger closing trajectory of 25 goals, open
loop and with the PID goal correction of Eq. 5.14; plots and errors.

Needs the models of table_5_1.py (or any `pliant condensed train` output):

    python experiments/condensed/trajectories.py experiments/condensed/results/finger_6500.pt
    pliant condensed control experiments/condensed/results/diamond_6500.pt --goals 30 \
        --pid 0.5,0.1,0

The error of Table 5.8 is |d_exact - d_learned| / d_exact, d the mean effector-goal distance.
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

GOALS = {"diamond": ("circle", 30, (0, 1)), "finger": ("closing", 25, (0, 2))}


def main(
    model: Annotated[Path, typer.Argument(help="learned model file")],
    iterations: Annotated[int, typer.Option()] = 5,
    pid: Annotated[str, typer.Option(help="K,I,D of the closed loop")] = "0.5,0.1,0",
    out: Annotated[Path, typer.Option()] = Path("experiments/condensed/results"),
) -> None:
    learned = LearnedCondensedModel.load(model)
    robot = learned.plan.robot
    name, n, plane = GOALS[robot]
    goals = robots.entry(robot).trajectories[name](n)
    fem = robots.build(robot, **learned.plan.robot_kwargs)
    report = {}
    for loop, gains in (("open", None), ("closed", [float(v) for v in pid.split(",")])):
        reached = {}
        for source_name, source in (
            ("learned", learned),
            ("exact", ExactCondensed(fem, StaticSolver(fem))),
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
        report[loop] = {
            "mean_distance": d,
            "table_5_8_error": abs(d["exact"] - d["learned"]) / d["exact"],
            "learned_vs_exact_gap": float(
                np.linalg.norm(
                    reached["learned"].reached - reached["exact"].reached, axis=-1
                ).mean()
            ),
        }
        plot_reached(
            goals,
            {k: r.reached[:, 0] for k, r in reached.items()},
            out / f"{robot}_{name}_{loop}.png",
            plane=plane,
            title=f"{robot} {name}, {loop} loop: learned vs exact",
        )
        print(robot, loop, json.dumps(report[loop]))
    (out / f"{robot}_{name}_trajectories.json").write_text(json.dumps(report, indent=1))


if __name__ == "__main__":
    typer.run(main)
