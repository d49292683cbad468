"""``pliant trajopt SCENARIO``: DDP on condensed FEM dynamics; plots, a GIF, a JSON report
(:mod:`pliant.trajopt.runs`)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from pliant.cli.support import at_least_one, non_negative, one_of, output_folder, positive
from pliant.trajopt.runs import (
    BACKENDS,
    run_diamond,
    run_diamond_mpc,
    run_learned_mpc,
    run_scenario,
)

app = typer.Typer(
    add_completion=False,
    no_args_is_help=True,
    help="Trajectory optimisation with condensed FEM dynamics (thesis §5.2).",
)


# Options the scenario commands share.
MaxIterations = Annotated[int, typer.Option(help="DDP iterations at most", callback=at_least_one)]
Tolerance = Annotated[
    float, typer.Option(help="relative cost decrease to stop", callback=non_negative)
]
Frames = Annotated[int, typer.Option(help="frames in each GIF (0: no GIF)", callback=non_negative)]
Out = Annotated[Path, typer.Option(help="output folder", callback=output_folder)]
# ... and the MPC commands'.
Horizon = Annotated[int, typer.Option(help="prediction nodes", callback=at_least_one)]
Iterations = Annotated[
    int, typer.Option(help="DDP iterations per control step", callback=at_least_one)
]
ControlSteps = Annotated[
    int, typer.Option(help="control steps (the task's nodes)", callback=at_least_one)
]


@app.command()
def diamond(
    nonlinear: Annotated[
        bool, typer.Option(help="also solve with the non-linear part of Eq. 5.27")
    ] = True,
    backend: Annotated[
        str,
        typer.Option(help="backward pass: numpy or crocoddyl", callback=one_of(*BACKENDS)),
    ] = "numpy",
    mesh_size: Annotated[
        float, typer.Option(help="Diamond mesh size (mm)", callback=positive)
    ] = 20.0,
    dt: Annotated[float, typer.Option(help="time step (s)", callback=positive)] = 0.02,
    horizon: Annotated[int, typer.Option(help="nodes N", callback=at_least_one)] = 100,
    max_iterations: MaxIterations = 100,
    tolerance: Tolerance = 1e-4,
    frames: Frames = 25,
    settle: Annotated[
        float, typer.Option(help="seconds of constant tensions per goal", callback=non_negative)
    ] = 3.0,
    out: Out = Path("out/trajopt"),
) -> None:
    """The Diamond's effector to two successive goals (Fig. 5.20), linear part of the state
    derivative and, with --nonlinear, the non-linear one (the thesis' lift)."""
    run_diamond(
        nonlinear=nonlinear,
        backend=backend,
        mesh_size=mesh_size,
        dt=dt,
        horizon=horizon,
        max_iterations=max_iterations,
        tolerance=tolerance,
        frames=frames,
        settle=settle,
        out=out,
    )


@app.command("diamond-mpc")
def diamond_mpc(
    horizon: Horizon = 20,
    iterations: Iterations = 3,
    mesh_size: Annotated[
        float, typer.Option(help="Diamond mesh size (mm)", callback=positive)
    ] = 20.0,
    dt: Annotated[float, typer.Option(help="time step (s)", callback=positive)] = 0.02,
    steps: ControlSteps = 100,
    settle: Annotated[
        float, typer.Option(help="seconds of constant tensions per goal", callback=non_negative)
    ] = 3.0,
    out: Out = Path("out/trajopt"),
) -> None:
    """The Diamond's two-goal task by receding-horizon MPC on the condensed dynamics frozen at
    each FEM state, the loop closed on the FEM: loop rate and tracking error."""
    run_diamond_mpc(
        horizon=horizon,
        iterations=iterations,
        mesh_size=mesh_size,
        dt=dt,
        steps=steps,
        settle=settle,
        out=out,
    )


def _command(command: str, doc: str) -> None:
    def run(
        quick: Annotated[bool, typer.Option(help="short horizon, 2 iterations (tests)")] = False,
        horizon: Annotated[
            int, typer.Option(help="nodes N (0: the scenario's)", callback=non_negative)
        ] = 0,
        max_iterations: MaxIterations = 100,
        tolerance: Tolerance = 1e-4,
        frames: Frames = 20,
        out: Out = Path("out/trajopt"),
    ) -> None:
        # Errors reach the command line's handler: one line, exit 1 (pliant.cli.support).
        run_scenario(
            command,
            quick=quick,
            horizon=horizon or None,
            max_iterations=max_iterations,
            tolerance=tolerance,
            frames=frames,
            out=out,
        )

    run.__doc__ = doc
    app.command(command)(run)


_command(
    "stiff-flop",
    "The Stiff-Flop's effector at the middle and at the tip to a goal (Fig. 5.21), pressures"
    " bounded in bar.",
)
_command("lianford-spiral", "The Lianford's handle along a spiral, a goal every step (Fig. 5.22).")
_command(
    "lianford-pick-place",
    "The Lianford's handle back and forth between two positions (Fig. 5.22).",
)
_command(
    "lianford-orientation",
    "Two effectors on the Lianford's ring at once: the handle's orientation (Fig. 5.22).",
)


def _learned_command(robot: str) -> None:
    def run(
        model: Annotated[
            Path | None,
            typer.Option(
                help="learned condensed model (default: experiments/results/trajopt/learned/"
                "ROBOT.pt, collected and trained there first if missing)"
            ),
        ] = None,
        horizon: Horizon = 20,
        iterations: Iterations = 3,
        steps: ControlSteps = 100,
        samples: Annotated[
            int, typer.Option(help="samples if a model is collected", callback=at_least_one)
        ] = 300,
        epochs: Annotated[
            int, typer.Option(help="epochs if a model is trained", callback=at_least_one)
        ] = 1000,
        out: Out = Path("out/trajopt"),
    ) -> None:
        run_learned_mpc(
            robot,
            model=model,
            horizon=horizon,
            iterations=iterations,
            steps=steps,
            samples=samples,
            epochs=epochs,
            out=out,
        )

    run.__doc__ = (
        f"The {robot.capitalize()}'s two-goal task by MPC whose prediction is the learned"
        " condensed model (§6.2.1), closed on the full FEM, beside the full-FEM DDP and the MPC"
        " on the frozen FEM condensed dynamics: loop rates and tracking errors."
    )
    app.command(f"{robot}-mpc-learned")(run)


_learned_command("diamond")
_learned_command("finger")
