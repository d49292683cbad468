"""``pliant trajopt SCENARIO``: DDP on condensed FEM dynamics; plots, a GIF, a JSON report
(:mod:`pliant.trajopt.runs`)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import numpy as np
import typer
from rich.console import Console
from rich.table import Table

from pliant.cli.options import OutFolder, option
from pliant.cli.support import at_least_one, command_group, non_negative, one_of, positive
from pliant.files import write_json
from pliant.trajopt.runs import (
    BACKENDS,
    run_learned_mpc,
    run_scenario,
    summary,
)

app = command_group("Trajectory optimisation with condensed FEM dynamics (thesis §5.2).")
console = Console()


# Options the scenario commands share.
MaxIterations = Annotated[int, typer.Option(help="DDP iterations at most", callback=at_least_one)]
Tolerance = Annotated[
    float, typer.Option(help="relative cost decrease to stop", callback=non_negative)
]
Frames = Annotated[int, typer.Option(help="frames in each GIF (0: no GIF)", callback=non_negative)]
# ... the Diamond's two-goal task's.
MeshSize = Annotated[float, typer.Option(help="Diamond mesh size (mm)", callback=positive)]
Seconds = Annotated[float, typer.Option(help="time step (s)", callback=positive)]
Settle = Annotated[
    float, typer.Option(help="seconds of constant tensions per goal", callback=non_negative)
]
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
        str, option("backward pass: numpy or crocoddyl", one_of(*BACKENDS))
    ] = "numpy",
    mesh_size: MeshSize = 20.0,
    dt: Seconds = 0.02,
    horizon: Annotated[int, option("nodes N", at_least_one)] = 100,
    max_iterations: MaxIterations = 100,
    tolerance: Tolerance = 1e-4,
    frames: Frames = 25,
    settle: Settle = 3.0,
    out: OutFolder = Path("out/trajopt"),
) -> None:
    """The Diamond's effector to two successive goals (Fig. 5.20), linear part of the state
    derivative and, with --nonlinear, the non-linear one (the thesis' lift)."""
    from pliant.trajopt.ddp import BoxDDP
    from pliant.trajopt.plots import plot_trajectory
    from pliant.trajopt.scenarios import diamond_two_goals

    runs = {"linear": False, "non-linear": True} if nonlinear else {"linear": False}
    reports, trajectories = [], {}
    solver = BoxDDP(max_iterations=max_iterations, tolerance=tolerance, backend=backend)
    for name, part in runs.items():
        scenario = diamond_two_goals(
            mesh_size=mesh_size, dt=dt, horizon=horizon, nonlinear=part, settle=settle
        )
        with console.status(f"diamond, {name} state derivative"):
            result = solver.solve(scenario.dynamics, scenario.start, scenario.cost, scenario.bounds)
        reports.append(summary(name, result, scenario))
        trajectories[name] = (result.xs, result.us)
        if name == "linear":
            best, best_scenario = result, scenario
    table = Table(title="Diamond, two goals: box-DDP on condensed FEM dynamics")
    for col in ("run", "iterations", "converged", "cost", "wall (s)", "end error (mm)"):
        table.add_column(col)
    for r in reports:
        table.add_row(
            r["run"],
            str(r["iterations"]),
            str(r["converged"]),
            f"{r['cost']:.4g}",
            f"{r['wall_time_s']:.1f}",
            f"{r['error_final_goal_at_end']:.3f}",
        )
    console.print(table)
    out.mkdir(parents=True, exist_ok=True)
    times = np.arange(horizon + 1) * dt
    bounds = (best_scenario.bounds.lower, best_scenario.bounds.upper)
    plot = plot_trajectory(
        times,
        trajectories,
        best_scenario.goals,
        bounds,
        out / "diamond.png",
        title="Diamond: two successive goals (box-DDP, full-FEM forward pass)",
    )
    written = [plot]
    if frames > 0:
        from pliant.viz import save_gif
        from pliant.viz.model_view import RobotCamera

        camera = RobotCamera(best_scenario.model, view=(20.0, -60.0))
        states = best.rollout.states
        picks = np.unique(np.linspace(0, len(states) - 1, frames).round().astype(int))
        images = [
            camera.frame(
                states[k],
                goals=best_scenario.goals[k][None],
                title=f"diamond DDP  t = {k * dt:.2f} s",
            )
            for k in picks
        ]
        written.append(save_gif(images, out / "diamond.gif", fps=10))
    report = out / "diamond.json"
    write_json(report, {"scenario": "diamond", "runs": reports})
    written.append(report)
    console.print("saved " + ", ".join(str(p) for p in written))


@app.command("diamond-mpc")
def diamond_mpc(
    horizon: Horizon = 20,
    iterations: Iterations = 3,
    mesh_size: MeshSize = 20.0,
    dt: Seconds = 0.02,
    steps: ControlSteps = 100,
    settle: Settle = 3.0,
    out: OutFolder = Path("out/trajopt"),
) -> None:
    """The Diamond's two-goal task by receding-horizon MPC on the condensed dynamics frozen at
    each FEM state, the loop closed on the FEM: loop rate and tracking error."""
    from pliant.trajopt.mpc import CondensedMPC
    from pliant.trajopt.plots import plot_trajectory
    from pliant.trajopt.scenarios import diamond_two_goals

    scenario = diamond_two_goals(mesh_size=mesh_size, dt=dt, horizon=steps, settle=settle)
    mpc = CondensedMPC(
        scenario.dynamics,
        scenario.cost,
        scenario.bounds,
        horizon=horizon,
        max_iterations=iterations,
    )
    with console.status("diamond MPC"):
        result = mpc.run(scenario.start)
    goals = scenario.goals
    errors = np.linalg.norm(result.xs[:, : goals.shape[1]] - goals, axis=1)
    report = {
        "scenario": "diamond-mpc",
        "horizon": horizon,
        "iterations_per_step": iterations,
        **result.report(),
        "cost": scenario.cost.value(result.xs, result.us),
        "rms_to_goals_mm": float(np.sqrt(np.mean(errors**2))),
        "end_error_mm": float(errors[-1]),
        "bound_violation": scenario.bounds.violation(result.us),
    }
    console.print(
        f"MPC horizon {horizon}: controller {report['loop_rate_hz']:.0f} Hz, closed loop with"
        f" the FEM {report['closed_loop_rate_hz']:.0f} Hz; RMS to the goals"
        f" {report['rms_to_goals_mm']:.2f} mm, end error {report['end_error_mm']:.3f} mm"
    )
    out.mkdir(parents=True, exist_ok=True)
    plot = plot_trajectory(
        np.arange(steps + 1) * dt,
        {f"MPC, horizon {horizon}": (result.xs, result.us)},
        goals,
        (scenario.bounds.lower, scenario.bounds.upper),
        out / "diamond_mpc.png",
        title="Diamond: MPC closed on the FEM",
    )
    path = out / "diamond_mpc.json"
    write_json(path, report)
    console.print(f"saved {plot}, {path}")


def _command(command: str, doc: str) -> None:
    def run(
        quick: Annotated[bool, typer.Option(help="short horizon, 2 iterations (tests)")] = False,
        horizon: Annotated[int, option("nodes N (0: the scenario's)", non_negative)] = 0,
        max_iterations: MaxIterations = 100,
        tolerance: Tolerance = 1e-4,
        frames: Frames = 20,
        out: OutFolder = Path("out/trajopt"),
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
        samples: Annotated[int, option("samples if a model is collected", at_least_one)] = 300,
        epochs: Annotated[int, option("epochs if a model is trained", at_least_one)] = 1000,
        out: OutFolder = Path("out/trajopt"),
    ) -> None:
        run_learned_mpc(**{**locals(), "robot": robot})  # the options, by name

    run.__doc__ = (
        f"The {robot.capitalize()}'s two-goal task by MPC whose prediction is the learned"
        " condensed model (§6.2.1), closed on the full FEM, beside the full-FEM DDP and the MPC"
        " on the frozen FEM condensed dynamics: loop rates and tracking errors."
    )
    app.command(f"{robot}-mpc-learned")(run)


_learned_command("diamond")
_learned_command("finger")
