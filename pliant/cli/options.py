"""Options that several commands declare alike, declared once as typer ``Annotated`` aliases.

A command names the parameter and its default; the alias brings the option's type, help and
check (:mod:`pliant.cli.support`), e.g. ``out: OutFolder = Path("out")``. An option whose help
says something particular to its command stays declared in that command.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Annotated, Any

import typer

from pliant import robots
from pliant.cli.support import at_least_one, non_negative, one_of, output_folder, positive

ROBOT_NAMES = ", ".join(sorted(robots.ROBOTS))

RobotName = Annotated[str, typer.Argument(help=f"one of {ROBOT_NAMES}")]
OutFolder = Annotated[Path, typer.Option(help="output folder", callback=output_folder)]
TimeStep = Annotated[float, typer.Option(help="time step", callback=positive)]
SolverKind = Annotated[
    str, typer.Option(help="dynamic or static", callback=one_of("dynamic", "static"))
]
MeshDirs = Annotated[list[Path], typer.Option(help="where a scene's meshes are")]
Goals = Annotated[int, typer.Option(help="number of goals", callback=at_least_one)]
Seed = Annotated[int, typer.Option()]
# Unexplained numbers with a check: counts (epochs, iterations, episodes) and rates.
Count = Annotated[int, typer.Option(callback=at_least_one)]
PositiveNumber = Annotated[float, typer.Option(callback=positive)]
NonNegativeNumber = Annotated[float, typer.Option(callback=non_negative)]


def option(help: str, check: Callable | None = None) -> Any:
    """A typer option with its help and the check of its value (:mod:`pliant.cli.support`),
    for an option particular to one command: ``Annotated[float, option("time step",
    positive)]``."""
    return typer.Option(help=help, callback=check)


def goal_trajectory(robot: str, entry, trajectory: str, goals: int):
    """The name and the `goals` goals of `robot`'s goal trajectory `trajectory` (its first
    one if ''); BadParameter if it has no such trajectory."""
    name = trajectory or next(iter(entry.trajectories))
    if name not in entry.trajectories:
        raise typer.BadParameter(
            f"{robot} has trajectories {sorted(entry.trajectories)}, not {name!r}"
        )
    return name, entry.trajectories[name](goals)
