"""``pliant proxy calibrate ROBOT``: fit a beam-skeleton proxy to its FEM robot (thesis
§4.1.1); a JSON report of the parameters and errors, the study in SQLite (resumable)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console

from pliant.cli_support import at_least_one, fraction, one_of, output_folder

app = typer.Typer(
    add_completion=False,
    no_args_is_help=True,
    help="Beam-skeleton proxies of FEM robots (thesis §4.1).",
)
console = Console()


@app.command()
def calibrate(
    robot: Annotated[
        str, typer.Argument(help="multigait or trunk", callback=one_of("multigait", "trunk"))
    ],
    trials: Annotated[
        int, typer.Option(help="trials the study is to hold", callback=at_least_one)
    ] = 40,
    safety: Annotated[
        float,
        typer.Option(help="factor in (0, 1] on the calibrated max curvatures", callback=fraction),
    ] = 0.9,
    seed: Annotated[int, typer.Option(help="TPE sampler seed")] = 0,
    reference: Annotated[
        Path | None, typer.Option(help="a saved FEM trajectory (.npz); made and saved if absent")
    ] = None,
    out: Annotated[Path, typer.Option(help="output folder", callback=output_folder)] = Path(
        "out/proxy"
    ),
) -> None:
    """Calibrate ROBOT's proxy on its FEM model: Optuna TPE, study resumed from
    OUT/ROBOT.db, report in OUT/ROBOT_calibration.json."""
    from pliant.proxy.calibrate import calibrate as fit
    from pliant.proxy.references import Reference, setup

    robot_setup = setup(robot)
    out.mkdir(parents=True, exist_ok=True)
    path = reference if reference is not None else out / f"{robot}_reference.npz"
    if path.exists():
        data = Reference.load(path)
    else:
        console.print(f"simulating the FEM {robot} for its reference trajectory")
        data = robot_setup.reference()
        data.save(path)
    result = fit(
        robot_setup.simulate(data),
        data.points,
        robot_setup.space,
        trials=trials,
        storage=f"sqlite:///{out / f'{robot}.db'}",
        study_name=robot,
        seed=seed,
        safety=safety,
    )
    report = {
        "robot": robot,
        "trials": result.trials,
        "optimisation_error_mm": result.optimisation_error,
        "validation_error_mm": result.validation_error,
        "parameters": result.parameters,
        "proxy_parameters": result.proxy_parameters,
        "safety": safety,
        "reference": str(path),
    }
    (out / f"{robot}_calibration.json").write_text(json.dumps(report, indent=2))
    console.print_json(json.dumps(report))
