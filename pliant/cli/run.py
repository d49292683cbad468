"""``pliant run``, ``pliant inverse``, ``pliant view``: a robot (or a SOFA scene) under its
scripted actuation, under inverse control, or in the browser."""

from __future__ import annotations

import json
import time
import warnings
from contextlib import nullcontext
from pathlib import Path
from typing import Annotated

import numpy as np
import typer
from rich.console import Console
from rich.progress import Progress
from rich.table import Table

from pliant import robots
from pliant.cli.options import (
    ROBOT_NAMES,
    Goals,
    MeshDirs,
    OutFolder,
    SolverKind,
    TimeStep,
    goal_trajectory,
    option,
)
from pliant.cli.support import (
    at_least_one,
    positive,
)
from pliant.errors import UnreachableGoalWarning
from pliant.files import write_json
from pliant.solvers import ImplicitEuler, StaticSolver

console = Console()


def _robot_or_scene(robot: str, mesh_dirs: list[Path]):
    """(scene, robot entry, name) of a robot's name, or of a SOFA scene file (`.scn`, `.xml`,
    `.py`, its meshes looked for in `mesh_dirs` too; the name is the file's stem)."""
    if robot.endswith((".scn", ".xml", ".py")):
        from pliant.sofa import load_scene

        scene = load_scene(robot, mesh_dirs=mesh_dirs)
        return scene, scene.entry(), Path(robot).stem
    return None, robots.entry(robot), robot


def _solver(model, solver: str, dt: float, scene=None):
    # A scene runs SOFA's step (its time step, refactorised every step) unless told otherwise.
    if scene is not None and solver == "dynamic":
        return scene.solver()
    if solver == "dynamic":
        return ImplicitEuler(model, dt)
    if solver == "static":
        return StaticSolver(model)
    raise typer.BadParameter(f"solver must be 'dynamic' or 'static', got {solver!r}")


def run(
    robot: Annotated[
        str,
        typer.Argument(help=f"one of {ROBOT_NAMES}, or a SOFA scene file"),
    ],
    duration: Annotated[float, option("simulated seconds", positive)] = 3.0,
    dt: TimeStep = 0.01,
    solver: SolverKind = "dynamic",
    frames: Annotated[int, option("frames in the GIF and VTU series", at_least_one)] = 30,
    out: OutFolder = Path("out"),
    mesh_dir: MeshDirs = [],  # noqa: B006
    states: Annotated[
        bool, typer.Option(help="also save the state at each frame (states/, for pliant view)")
    ] = False,
) -> None:
    """Simulate ROBOT (or a SOFA .scn / .py scene, under its commands) under its scripted
    actuation; save a GIF, a PNG and a VTU time series (and the states, with --states)."""
    from pliant.scenario import scripted
    from pliant.viz import VtuSeriesWriter, save_gif, save_png
    from pliant.viz.model_view import RobotCamera

    scene, entry, robot = _robot_or_scene(robot, mesh_dir)
    model = entry.build()
    sim = _solver(model, solver, dt, scene)
    n_steps = max(1, round(duration / dt))
    frames = max(1, min(frames, n_steps))
    frame_steps = set(np.linspace(n_steps / frames, n_steps, frames).round().astype(int))
    camera = RobotCamera(model, view=entry.view)
    folder = out / robot
    images = []
    state = start = model.rest_state()
    body = model.body  # None: rigid bodies alone (no VTU series, the frames only)
    cell_type, cells, rows = body.vtk_cells() if body is not None else (None, None, None)
    rest = body.rest_positions[rows] if body is not None else None
    if states:
        from pliant.viz.viewer import SERIES_FILE

        (folder / "states").mkdir(parents=True, exist_ok=True)
        write_json(folder / "states" / SERIES_FILE, {"robot": robot, "dt": dt}, indent=None)
    with (
        VtuSeriesWriter(folder, robot, cells, cell_type)
        if body is not None
        else nullcontext() as vtu,
        Progress(console=console) as bar,
    ):
        task = bar.add_task(f"{robot}: {n_steps} steps", total=n_steps)
        for state in scripted(sim, start, entry.demo_actuation, n_steps):  # noqa: B020
            bar.advance(task)
            if state.step in frame_steps:
                images.append(camera.frame(state, title=f"{robot}  t = {state.time:.2f} s"))
                if vtu is not None:
                    vtu.write(
                        state.time,
                        state.positions[rows],
                        {
                            "displacement": state.positions[rows] - rest,
                            "velocity": state.velocities[rows],
                        },
                    )
                if states:
                    state.save(folder / "states" / f"state_{state.step:06d}.npz")
    gif = save_gif(images, folder / f"{robot}.gif", fps=15)
    png = save_png(images[-1], folder / f"{robot}.png")
    if body is None:
        console.print(f"{len(model.rigid_bodies)} rigid bodies, {n_steps} steps")
        console.print(f"saved {gif} and {png}")
        return
    console.print(
        f"{body.label}, {n_steps} steps; actuation"
        f" {np.round(state.actuation, 2).tolist()} -> displacement"
        f" {np.round(state.displacement, 2).tolist()}"
    )
    console.print(f"saved {gif}, {png} and {vtu.pvd_path}")


def inverse(
    robot: Annotated[
        str,
        typer.Argument(help=f"one of {ROBOT_NAMES}, or a SOFA scene file with a PositionEffector"),
    ],
    trajectory: Annotated[
        str, typer.Option(help="goal trajectory of the robot (circle, closing, ...)")
    ] = "",
    goals: Goals = 30,
    dt: TimeStep = 0.01,
    solver: SolverKind = "dynamic",
    max_steps: Annotated[int, option("steps at most per goal", at_least_one)] = 60,
    out: OutFolder = Path("out"),
    mesh_dir: MeshDirs = [],  # noqa: B006
) -> None:
    """Inverse control (QP, Eq. 2.15) of ROBOT's effector along a goal trajectory (a scene's:
    `goal`, GOALS steps on the line from the effector to its effectorGoal)."""
    from pliant.scenario import track_goals
    from pliant.viz import plot_trajectory, save_gif
    from pliant.viz.model_view import RobotCamera

    scene, entry, robot = _robot_or_scene(robot, mesh_dir)
    if not entry.trajectories and scene is not None:
        raise typer.BadParameter(f"{robot} has no PositionEffector to control")
    if not entry.trajectories:
        having = sorted(k for k, e in robots.ROBOTS.items() if e.trajectories)
        raise typer.BadParameter(
            f"{robot} has no goal trajectory for inverse control; robots with one:"
            f" {', '.join(having)}"
        )
    name, targets = goal_trajectory(robot, entry, trajectory, goals)
    model = entry.build()
    sim = _solver(model, solver, dt, scene)
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
        with warnings.catch_warnings():  # goals out of reach are counted below instead
            warnings.simplefilter("ignore", UnreachableGoalWarning)
            for goal in targets:
                res, state = track_goals(
                    model, sim, state, goal[None], max_steps=max_steps, on_step=on_step
                )
                results += res
                bar.advance(task)
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
    far = [i for i, r in enumerate(results) if r.out_of_reach]
    if far:
        console.print(
            f"{len(far)} of {len(results)} goals out of reach (#{', #'.join(map(str, far))}):"
            " reached is the closest configuration within the actuators' bounds"
        )
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
                "out_of_reach": [r.out_of_reach for r in results],
            },
            indent=1,
        )
    )
    console.print(f"saved {plot}, {gif}, {report}")


def open_viewer(
    target: str,
    *,
    host: str = "127.0.0.1",
    port: int = 8080,
    dt: float = 0.01,
    policy: Path | None = None,
    playing: bool = True,
    robot: str | None = None,
):
    """The viewer of a robot name, an environment id, a run folder or saved states (checked
    before any server starts).

    Saved states (an ``.npz`` file, a folder of them, or a run folder with ``states/``) are
    drawn with the model of `robot`, by default the one their ``series.json`` names."""
    import pliant.envs as envs
    from pliant.viz.viewer import (
        EnvironmentViewer,
        PlaybackViewer,
        SimulationViewer,
        StatePlaybackViewer,
        ViewerError,
        load_policy,
        read_states,
        series_robot,
        state_files,
    )

    if target in robots.ROBOTS:
        model = robots.build(target)
        return SimulationViewer(
            model, ImplicitEuler(model, dt=dt), host=host, port=port, playing=playing
        )
    names = {f"pliant/{n}-v0": n for n in envs.ENVS}
    if target in names or target in envs.ENVS:
        env_id = target if target in names else f"pliant/{target}-v0"
        act = None if policy is None else load_policy(policy)
        return EnvironmentViewer(
            envs.make(env_id), policy=act, host=host, port=port, playing=playing
        )
    files = state_files(Path(target))
    if files:
        name = robot or series_robot(files)
        if name not in robots.ROBOTS:
            raise ViewerError(
                f"{target}: saved states need their robot: give --robot"
                f" ({', '.join(sorted(robots.ROBOTS))})"
                + ("" if name is None else f", not {name!r}")
            )
        model = robots.build(name)
        return StatePlaybackViewer(model, read_states(files, model), host=host, port=port)
    if Path(target).is_dir():
        return PlaybackViewer(Path(target), host=host, port=port)
    raise ViewerError(
        f"{target!r} is not a robot ({', '.join(sorted(robots.ROBOTS))}), an environment"
        f" ({', '.join(sorted(names))}), a folder of a run or saved states (.npz)"
    )


def view(
    target: Annotated[
        str,
        typer.Argument(
            help="a robot (live, sliders and a draggable goal), an environment id"
            " (pliant/Name-v0: an episode), a folder `pliant run` wrote or saved states"
            " (.npz file or folder) (playback)"
        ),
    ],
    port: Annotated[int, typer.Option(help="port (the next free one if taken)")] = 8080,
    host: Annotated[str, typer.Option(help="interface to serve on")] = "127.0.0.1",
    dt: Annotated[float, typer.Option(help="time step of a live robot")] = 0.01,
    policy: Annotated[
        Path | None, typer.Option(help="a Stable-Baselines3 model (.zip) to act in an environment")
    ] = None,
    robot: Annotated[
        str | None, typer.Option(help="the robot of saved states (default: their series.json)")
    ] = None,
) -> None:
    """Open ROBOT, ENV or RUN_DIR in the browser (viser): the simulation live, actuators on
    sliders, a goal to drag for inverse control, play/pause/step/reset, playback of a run."""
    from pliant.viz.viewer import ViewerError

    try:
        viewer = open_viewer(target, host=host, port=port, dt=dt, policy=policy, robot=robot)
    except ViewerError as exc:  # nothing to show: a usage error, before any server starts
        raise typer.BadParameter(str(exc), param_hint="TARGET") from exc
    console.print(f"Pliant viewer of {target}: {viewer.url}  (Ctrl-C to stop)")
    viewer.start()
    try:
        while True:
            time.sleep(1.0)
    except KeyboardInterrupt:
        viewer.stop()
