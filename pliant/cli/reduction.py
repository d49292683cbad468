"""``pliant reduce ROBOT``: snapshots of the full FEM -> POD basis -> ECSW -> a saved reduced
model, with a report of its modes, selected elements, errors and speed."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console
from rich.progress import Progress
from rich.table import Table

from pliant import robots
from pliant.cli.options import RobotName, TimeStep, option
from pliant.cli.support import at_least_one, non_negative, open_fraction, output_folder, positive
from pliant.reduction.pipeline import compare, multigait_cases, reduce, robot_cases

console = Console()


def reduce_command(
    robot: RobotName,
    out: Annotated[
        Path, option("folder of snapshots.h5, reduced.npz, report.json", output_folder)
    ] = Path("out/reduction"),
    dt: TimeStep = 0.01,
    pod_tolerance: Annotated[
        float, option("tail energy of the modes left out", open_fraction)
    ] = 1e-3,
    tau: Annotated[float, option("ECSW tolerance of the tetrahedra", open_fraction)] = 3e-3,
    tau_membrane: Annotated[float, option("ECSW tolerance of the membranes", open_fraction)] = 3e-3,
    duration: Annotated[float, option("seconds of scripted actuation", positive)] = 3.6,
    phase: Annotated[float, option("seconds of a ramp of the load cases", non_negative)] = 0.6,
    sequences: Annotated[int, option("multigait: random action sequences", at_least_one)] = 3,
    check: Annotated[float, option("seconds of scripted actuation to compare", positive)] = 1.2,
    workers: Annotated[int, option("local processes running the load cases", at_least_one)] = 1,
    ray: Annotated[
        str | None, typer.Option(help="run the load cases on this Ray cluster (auto, ray://...)")
    ] = None,
) -> None:
    """Reduce ROBOT (thesis §3.1.2): full-FEM snapshots of its load cases (resumable),
    POD basis, ECSW integration domain; save the reduced model and report its modes,
    selected elements, errors against the full FEM and speed."""
    entry = robots.entry(robot)
    model = entry.build()
    if robot == "multigait":
        cases = multigait_cases(phase=phase, sequences=sequences)
    else:
        cases = robot_cases(entry, duration, phase)
    folder = out / robot
    with Progress(console=console) as bar:
        tasks: dict[str, int] = {}

        def progress(name: str, step: int, steps: int) -> None:
            if name not in tasks:
                tasks[name] = bar.add_task(f"full FEM: {name}", total=steps)
            bar.update(tasks[name], completed=step)

        reduced = reduce(
            model,
            cases,
            folder,
            dt=dt,
            workers=workers,
            ray_address=ray,
            progress=progress,
            pod_tolerance=pod_tolerance,
            tau=tau,
            tau_membrane=tau_membrane,
        )
    report = {**reduced.metadata, **compare(model, reduced, entry, dt, check)}
    (folder / "report.json").write_text(json.dumps(report, indent=1))
    table = Table(title=f"{robot}: reduced model ({folder / 'reduced.npz'})")
    table.add_column("")
    table.add_column("value")
    rows = [
        ("modes (translations)", f"{report['n_modes']} ({report['n_translation']})"),
        ("tetrahedra selected", f"{report['tets_selected']} / {report['tets_total']}"),
        (
            "membrane triangles selected",
            f"{report['triangles_selected']} / {report['triangles_total']}",
        ),
        (
            "ECSW error (training)",
            f"{report['ecsw_error_tets']:.2g} {report['ecsw_error_membranes']}",
        ),
        ("snapshot projection error, max", f"{report['projection_error_max_mm']:.3g}"),
        (
            f"error vs full over {check} s, max / RMS",
            f"{report['max_error']:.3g} / {report['rms_error']:.3g}",
        ),
        (
            "steps/s full / reduced",
            f"{report['full_steps_per_s']:.1f} / {report['reduced_steps_per_s']:.1f}",
        ),
    ]
    for row in rows:
        table.add_row(*row)
    console.print(table)
    console.print(f"saved {folder / 'reduced.npz'} and {folder / 'report.json'}")
