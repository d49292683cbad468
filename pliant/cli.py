"""The ``pliant`` command line: run, inverse, bench."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import numpy as np
import typer
from rich.console import Console
from rich.progress import Progress
from rich.table import Table

from pliant import robots
from pliant.condensed.cli import app as condensed_app
from pliant.errors import PliantError
from pliant.learn import cli as learn_cli
from pliant.solvers import ImplicitEuler, StaticSolver

app = typer.Typer(
    add_completion=False,
    no_args_is_help=True,
    help="Simulate, control and benchmark FEM soft robots.",
)
console = Console()
app.add_typer(condensed_app, name="condensed")
app.command("train")(learn_cli.train)
app.command("eval")(learn_cli.eval_)
app.command("enjoy")(learn_cli.enjoy)
app.command("tune")(learn_cli.tune)


def _solver(model, solver: str, dt: float):
    if solver == "dynamic":
        return ImplicitEuler(model, dt)
    if solver == "static":
        return StaticSolver(model)
    raise typer.BadParameter(f"solver must be 'dynamic' or 'static', got {solver!r}")


@app.command()
def run(
    robot: Annotated[str, typer.Argument(help=f"one of {', '.join(sorted(robots.ROBOTS))}")],
    duration: Annotated[float, typer.Option(help="simulated seconds")] = 3.0,
    dt: Annotated[float, typer.Option(help="time step")] = 0.01,
    solver: Annotated[str, typer.Option(help="dynamic or static")] = "dynamic",
    frames: Annotated[int, typer.Option(help="frames in the GIF and VTU series")] = 30,
    out: Annotated[Path, typer.Option(help="output folder")] = Path("out"),
) -> None:
    """Simulate ROBOT under its scripted actuation; save a GIF, a PNG and a VTU time series."""
    from pliant.scenario import scripted
    from pliant.viz import VtuSeriesWriter, save_gif, save_png
    from pliant.viz.model_view import RobotCamera

    try:
        entry = robots.entry(robot)
        model = entry.build()
        sim = _solver(model, solver, dt)
        n_steps = max(1, round(duration / dt))
        frames = max(1, min(frames, n_steps))
        frame_steps = set(np.linspace(n_steps / frames, n_steps, frames).round().astype(int))
        camera = RobotCamera(model, view=entry.view)
        folder = out / robot
        images = []
        state = start = model.rest_state()
        cell_type, cells, rows = model.body.vtk_cells()
        rest = model.body.rest_positions[rows]
        with (
            VtuSeriesWriter(folder, robot, cells, cell_type) as vtu,
            Progress(console=console) as bar,
        ):
            task = bar.add_task(f"{robot}: {n_steps} steps", total=n_steps)
            for state in scripted(sim, start, entry.demo_actuation, n_steps):  # noqa: B020
                bar.advance(task)
                if state.step in frame_steps:
                    images.append(camera.frame(state, title=f"{robot}  t = {state.time:.2f} s"))
                    vtu.write(
                        state.time,
                        state.positions[rows],
                        {
                            "displacement": state.positions[rows] - rest,
                            "velocity": state.velocities[rows],
                        },
                    )
        gif = save_gif(images, folder / f"{robot}.gif", fps=15)
        png = save_png(images[-1], folder / f"{robot}.png")
    except PliantError as exc:
        console.print(f"[red]error:[/red] {exc}")
        raise typer.Exit(1) from exc
    console.print(
        f"{model.body.label}, {n_steps} steps; actuation"
        f" {np.round(state.actuation, 2).tolist()} -> displacement"
        f" {np.round(state.displacement, 2).tolist()}"
    )
    console.print(f"saved {gif}, {png} and {vtu.pvd_path}")


@app.command()
def inverse(
    robot: Annotated[str, typer.Argument(help=f"one of {', '.join(sorted(robots.ROBOTS))}")],
    trajectory: Annotated[
        str, typer.Option(help="goal trajectory of the robot (circle, closing, ...)")
    ] = "",
    goals: Annotated[int, typer.Option(help="number of goals")] = 30,
    dt: Annotated[float, typer.Option(help="time step")] = 0.01,
    solver: Annotated[str, typer.Option(help="dynamic or static")] = "dynamic",
    max_steps: Annotated[int, typer.Option(help="steps at most per goal")] = 60,
    out: Annotated[Path, typer.Option(help="output folder")] = Path("out"),
) -> None:
    """Inverse control (QP, Eq. 2.15) of ROBOT's effector along a goal trajectory."""
    from pliant.scenario import track_goals
    from pliant.viz import plot_trajectory, save_gif
    from pliant.viz.model_view import RobotCamera

    try:
        entry = robots.entry(robot)
        name = trajectory or next(iter(entry.trajectories))
        if name not in entry.trajectories:
            raise typer.BadParameter(
                f"{robot} has trajectories {sorted(entry.trajectories)}, not {name!r}"
            )
        targets = entry.trajectories[name](goals)
        model = entry.build()
        sim = _solver(model, solver, dt)
        camera = RobotCamera(model, view=entry.view)
        folder = out / robot
        images = []
        with Progress(console=console) as bar:
            task = bar.add_task(f"{robot} {name}", total=len(targets))

            def on_step(state, goal):
                if state.step % 3 == 0:
                    images.append(camera.frame(state, goals=goal, title=f"{robot} inverse: {name}"))

            results = []
            state = model.rest_state()
            for goal in targets:
                res, state = track_goals(
                    model, sim, state, goal[None], max_steps=max_steps, on_step=on_step
                )
                results += res
                bar.advance(task)
    except PliantError as exc:
        console.print(f"[red]error:[/red] {exc}")
        raise typer.Exit(1) from exc
    table = Table(title=f"{robot}: reached vs goal ({name})")
    for col in ("#", "goal", "reached", "error", "steps"):
        table.add_column(col)
    for i, r in enumerate(results):
        table.add_row(
            str(i),
            np.array2string(r.goal, precision=1),
            np.array2string(r.reached, precision=2),
            f"{r.error:.3f}",
            str(r.steps),
        )
    console.print(table)
    errors = np.array([r.error for r in results])
    console.print(f"error: mean {errors.mean():.3f}, max {errors.max():.3f} (mm for robot scenes)")
    plot = plot_trajectory(
        np.array([r.goal for r in results]),
        np.array([r.reached for r in results]),
        folder / f"{robot}_{name}.png",
        title=f"{robot}: inverse control ({name})",
    )
    gif = save_gif(images, folder / f"{robot}_{name}.gif", fps=20)
    report = folder / f"{robot}_{name}.json"
    report.write_text(
        json.dumps(
            {
                "robot": robot,
                "trajectory": name,
                "errors": errors.tolist(),
                "mean_error": float(errors.mean()),
                "max_error": float(errors.max()),
            },
            indent=1,
        )
    )
    console.print(f"saved {plot}, {gif}, {report}")


@app.command()
def bench(
    meshes: Annotated[Path | None, typer.Option(help="folder of the reference SOFA meshes")] = None,
    repeats: Annotated[int, typer.Option(help="timed repeats per scene (median reported)")] = 3,
    steps: Annotated[
        int, typer.Option(help="steps per timed repeat (scaled down for big scenes)")
    ] = 100,
    quick: Annotated[bool, typer.Option(help="small scenes only (a smoke run)")] = False,
    out: Annotated[Path, typer.Option(help="JSON results file")] = Path("bench-results/bench.json"),
) -> None:
    """Median steps/s beside SOFA's measured figures; writes JSON and a log-log plot."""
    from pliant.bench import run_benchmarks

    run_benchmarks(
        meshes=meshes, repeats=repeats, steps=steps, quick=quick, out=out, console=console
    )


if __name__ == "__main__":
    app()
