"""``pliant condensed``: collect a dataset, train F (and G), evaluate, control, calibrate,
design."""

from __future__ import annotations

import dataclasses
import math
import warnings
from pathlib import Path
from typing import Annotated

import numpy as np
import typer
from rich.console import Console
from rich.progress import Progress
from rich.table import Table
from rich.text import Text

from pliant import robots
from pliant.cli.options import (
    Count,
    Goals,
    NonNegativeNumber,
    OutFolder,
    PositiveNumber,
    RobotName,
    Seed,
    goal_trajectory,
    option,
)
from pliant.cli.support import (
    assignments,
    at_least_one,
    command_group,
    non_negative,
    numbers_list,
    one_of,
    output_file,
    positive,
)
from pliant.files import write_json

app = command_group(
    "Learned condensed FEM model (thesis §5.1): data, training, evaluation, control,"
    " calibration and design."
)
console = Console()


def _number_or_text(text: str) -> float | int | str | list:
    if "," in text:  # a vector, e.g. gravity=9810,0,0
        return [_number_or_text(part) for part in text.split(",")]
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    return text


def _interval(text: str) -> tuple[float, float]:
    try:
        low, high = (float(v) for v in text.split(":"))
    except ValueError:
        raise typer.BadParameter(f"expected LOW:HIGH, got {text!r}") from None
    if not (math.isfinite(low) and math.isfinite(high) and low <= high):
        raise typer.BadParameter(f"expected finite LOW <= HIGH, got {text!r}")
    return low, high


def _widths(text: str) -> tuple[int, ...]:
    """Option callback: comma-separated integers >= 1 (layer widths, grid counts)."""
    try:
        values = tuple(int(v) for v in text.split(","))
    except ValueError:
        raise typer.BadParameter(f"expected comma-separated integers, got {text!r}") from None
    if not all(v >= 1 for v in values):
        raise typer.BadParameter(f"every value must be >= 1, got {text!r}")
    return values


def _gains(text: str) -> tuple[float, ...]:
    """Option callback: '' (no PID) or K,I,D, three finite numbers."""
    return tuple(numbers_list(text, "K,I,D", count=3)) if text else ()


@app.command()
def collect(
    robot: RobotName,
    out: Annotated[Path, option("HDF5 dataset to write", output_file)],
    bounds: Annotated[
        list[str],
        typer.Option(help="LOW:HIGH of the actuator displacements, once for all or per actuator"),
    ],
    samples: Annotated[int, option("training samples (test: 25 %)", at_least_one)] = 6500,
    test_fraction: Annotated[float, option("test samples / training samples", non_negative)] = 0.25,
    seed: Annotated[int, typer.Option(help="seed of the sampling")] = 0,
    set_: Annotated[
        list[str] | None,
        typer.Option("--set", help="builder keyword NAME=VALUE, e.g. resolution=fine"),
    ] = None,
    design: Annotated[
        list[str] | None, typer.Option(help="design parameter NAME=LOW:HIGH sampled with the rest")
    ] = None,
    samples_per_design: Annotated[
        int, option("consecutive samples sharing one design (meshed once)", at_least_one)
    ] = 1,
    max_increment: Annotated[
        float, option("largest command change per static step (halved on failure)", positive)
    ] = 8.0,
    chunk_size: Annotated[int, option("samples per saved chunk", at_least_one)] = 16,
    contacts: Annotated[
        str, typer.Option(help="mesh landmark of fixed contact points (§5.1.4), held and recorded")
    ] = "",
    object_: Annotated[
        list[str] | None,
        typer.Option(
            "--object",
            help="LOW:HIGH of the held object's displacement: x, y, z (then rotation vector)",
        ),
    ] = None,
    sampling: Annotated[
        str,
        option(
            "box (Halton over the bounds) or gripper (inverse control)", one_of("box", "gripper")
        ),
    ] = "box",
    consistent_tangent: Annotated[
        bool,
        typer.Option(
            "--consistent-tangent/--material-tangent",
            help="W of the consistent tangent, or of SOFA's material tangent (the thesis')",
        ),
    ] = True,
    start: Annotated[
        str,
        option(
            "where each sample's load stepping starts: previous (the previous sample's"
            " equilibrium) or rest (its design's rest equilibrium: one equilibrium per command"
            " where the robot has several)",
            one_of("previous", "rest"),
        ),
    ] = "previous",
    workers: Annotated[
        int | None, option("local processes (default: one per CPU)", at_least_one)
    ] = None,
    ray: Annotated[str | None, typer.Option(help="Ray cluster address (auto, ray://...)")] = None,
    overwrite: Annotated[
        bool,
        typer.Option(
            help="replace OUT if it exists (a finished or corrupt dataset); the saved chunks of"
            " a partial collection of the same plan are kept and checked"
        ),
    ] = False,
) -> None:
    """Sample ROBOT's actuator displacements (scrambled Halton), solve each, write OUT.

    With --contacts, the contact points are held too, displaced rigidly by --object from where
    the actuators put them; --sampling gripper samples only the object's displacement, a cube
    held by three of the robot, the actuation found by inverse control (--bounds bound it).
    Rerun the same command to resume an interrupted collection (its saved chunks are
    checked; corrupt ones are solved again).
    """
    from pliant.condensed.collect import collect as run_collection
    from pliant.condensed.dataset import CollectionPlan

    # Every option read before the robot is built (meshing takes seconds).
    kwargs = {k: _number_or_text(v) for k, v in assignments(set_ or [], form="NAME=VALUE").items()}
    intervals = [_interval(b) for b in bounds]
    design_bounds = {
        k: _interval(v) for k, v in assignments(design or [], form="NAME=VALUE").items()
    }
    object_bounds = tuple(_interval(b) for b in object_ or [])
    n_act = robots.build(robot, **kwargs).n_actuators
    if len(intervals) == 1:
        intervals *= n_act
    if len(intervals) != n_act:
        raise typer.BadParameter(f"{robot} has {n_act} actuators, got {len(intervals)} bounds")
    plan = CollectionPlan(
        robot,
        tuple(intervals),
        samples,
        robot_kwargs=kwargs,
        design_bounds=design_bounds,
        test_fraction=test_fraction,
        seed=seed,
        max_increment=max_increment,
        samples_per_design=samples_per_design,
        chunk_size=chunk_size,
        contacts=contacts,
        object_bounds=object_bounds,
        sampling=sampling,
        consistent_tangent=consistent_tangent,
        start=start,
    )
    with Progress(console=console) as bar:
        task = bar.add_task(f"{robot}: sampled points", total=plan.n_train + plan.n_test)
        dataset = run_collection(
            plan,
            out,
            workers=workers,
            ray_address=ray,
            on_chunk=lambda done, total: bar.update(task, completed=done),
            overwrite=overwrite,
        )
    failed = {s: int((~dataset.split(s).converged.astype(bool)).sum()) for s in ("train", "test")}
    console.print(
        f"saved {out}: {len(dataset.train)} training and {len(dataset.test)} test samples"
        f" ({failed['train']} and {failed['test']} did not converge)"
    )


@app.command()
def verify(
    out: Annotated[Path, typer.Argument(help="HDF5 dataset (and its OUT.parts/ folder)")],
) -> None:
    """Check OUT and the saved chunks of its partial collection against their checksums.

    Lists every corrupt part (exit 1), so that a corrupt dataset is collected again with
    --overwrite and corrupt chunks are solved again by rerunning the same collect.
    """
    from pliant.condensed.collect import verify as find_problems
    from pliant.errors import DatasetError

    problems = find_problems(out)
    for problem in problems[:-1]:
        console.print(Text(f"bad: {problem}", style="red"), soft_wrap=True)
    if problems:
        raise DatasetError(f"{len(problems)} problem(s); last: {problems[-1]}")
    console.print(
        f"{out}: no corrupt part found (every checksum matches)", markup=False, soft_wrap=True
    )


@app.command()
def train(
    dataset: Annotated[Path, typer.Argument(help="HDF5 dataset")],
    out: Annotated[Path, option("learned model file to write (.pt)", output_file)],
    epochs: Count = 1000,
    batch_size: Count = 256,
    learning_rate: PositiveNumber = 1e-4,
    hidden: Annotated[str, option("hidden layer widths, comma separated", _widths)] = "450,450,450",
    dropout: NonNegativeNumber = 0.0,
    activation: Annotated[
        str, option("hidden activation", one_of("relu", "silu", "tanh"))
    ] = "relu",
    schedule: Annotated[
        str,
        option(
            "plateau (rate halved when the training loss stalls) or cosine (one cycle)",
            one_of("plateau", "cosine"),
        ),
    ] = "plateau",
    weight_decay: NonNegativeNumber = 0.0,
    seed: Seed = 0,
    log_dir: Annotated[Path | None, typer.Option(help="TensorBoard folder")] = None,
    checkpoint: Annotated[
        Path | None, typer.Option(help="checkpoint file, resumed from if it exists")
    ] = None,
) -> None:
    """Train F (3 x 450 ReLU MLP by default) on DATASET; keep the best epoch.

    Smooth compliances are fitted more closely with --activation silu --schedule cosine
    (Table 5.1's Diamond: docs/condensed.md).

    A dataset over design parameters also trains G (Eq. 5.7), with the same settings, and
    writes the parametric model F(delta_a, G(P)) that `calibrate` and `design` use.
    """
    from pliant.condensed.dataset import Dataset
    from pliant.condensed.parametric import train_parametric
    from pliant.condensed.train import TrainConfig, evaluate, train_condensed

    data = Dataset.load(dataset)
    config = TrainConfig(
        epochs=epochs,
        batch_size=batch_size,
        learning_rate=learning_rate,
        hidden=tuple(hidden),
        dropout=dropout,
        activation=activation,
        schedule=schedule,
        weight_decay=weight_decay,
        seed=seed,
        log_dir=log_dir,
        checkpoint=checkpoint,
    )
    if data.plan.design_names:
        design_config = dataclasses.replace(
            config,
            log_dir=None if log_dir is None else log_dir / "design",
            checkpoint=None if checkpoint is None else checkpoint.with_suffix(".g.ckpt"),
        )
        parametric, _ = train_parametric(data, config, design_config)
        parametric.save(out)
        losses = parametric.training
        console.print(
            f"saved {out}: F test loss {losses['condensed']['test_loss']:.3g} (best epoch"
            f" {losses['condensed']['best_epoch']}), G test loss"
            f" {losses['design']['test_loss']:.3g} (best epoch"
            f" {losses['design']['best_epoch']})"
        )
        return
    learned, result = train_condensed(data, config)
    learned.save(out)
    scores = evaluate(learned, data.test)
    if not scores["samples"]:
        console.print(
            f"saved {out}: best epoch {result.best_epoch} by the training loss"
            f" {result.best_test_loss:.3g} (no converged test sample to score it on)"
        )
        return
    console.print(
        f"saved {out}: best epoch {result.best_epoch}, standardised test loss"
        f" {scores['loss']:.3g} (constant-W0 baseline {scores['baseline_loss']:.3g})"
    )


@app.command()
def evaluate(
    model: Annotated[Path, typer.Argument(help="learned model file")],
    dataset: Annotated[Path, typer.Argument(help="HDF5 dataset")],
) -> None:
    """Standardised loss (Eq. 5.5) of MODEL on DATASET beside the constant-W0 baseline."""
    from pliant.condensed.dataset import Dataset
    from pliant.condensed.learned import LearnedCondensedModel
    from pliant.condensed.train import evaluate as scores_of

    learned = LearnedCondensedModel.load(model)
    data = Dataset.load(dataset)
    learned.layout.check_matches(data.layout, str(dataset))
    table = Table(title=f"{model.name} on {dataset.name}")
    for col in ("split", "samples", "loss", "constant-W0 baseline"):
        table.add_column(col)
    for name in ("train", "test"):
        s = scores_of(learned, data.split(name))
        table.add_row(name, str(s["samples"]), f"{s['loss']:.3g}", f"{s['baseline_loss']:.3g}")
    console.print(table)


@app.command()
def control(
    model: Annotated[Path, typer.Argument(help="learned model file")],
    trajectory: Annotated[str, typer.Option(help="goal trajectory of the robot")] = "",
    goals: Goals = 30,
    iterations: Annotated[int, option("control iterations per goal", at_least_one)] = 5,
    pid: Annotated[str, option("K,I,D of the goal correction (Eq. 5.14)", _gains)] = "",
    exact: Annotated[bool, typer.Option(help="also control with the exact FEM matrices")] = True,
    embedded: Annotated[
        int,
        typer.Option(
            help="also run the embedded loop this many iterations, report its rate",
            min=0,
        ),
    ] = 0,
    pressure: Annotated[
        bool,
        typer.Option(
            help="drive the actuators in force (pressure control): the learned model runs"
            " Algorithm 2 on its own actuator displacements, no actuator sensing"
        ),
    ] = False,
    out: OutFolder = Path("out"),
) -> None:
    """Control the FEM robot with MODEL along a trajectory, beside the exact matrices.

    Writes a plot (Fig. 5.4) and a JSON report to OUT.
    """
    from pliant.condensed.control import (
        PID,
        EmbeddedController,
        ExactCondensed,
        follow_embedded,
        follow_trajectory,
        loop_frequency,
    )
    from pliant.condensed.learned import LearnedCondensedModel, OutOfBoundsWarning
    from pliant.condensed.plots import plot_reached
    from pliant.solvers import StaticSolver

    learned = LearnedCondensedModel.load(model)
    plan = learned.plan
    entry = robots.entry(plan.robot)
    if not entry.trajectories:
        raise typer.BadParameter(f"{plan.robot} has no goal trajectory to control along")
    name, targets = goal_trajectory(plan.robot, entry, trajectory, goals)
    gains = list(pid)

    def controller() -> PID | None:
        return PID(*gains) if gains else None

    def follow(condensed, **options):
        """The robot controlled along the goals with `condensed` (a PID of its own each time)."""
        return follow_trajectory(
            robot,
            targets,
            condensed,
            iterations=iterations,
            pid=controller(),
            course=learned.input_box,
            max_increment=step,
            **options,
        )

    robot = robots.build(plan.robot, **plan.robot_kwargs)
    # the plant's load steps: the collection's in displacement, the whole force range in force
    spans = [a.max_force - a.min_force for a in learned.layout.actuators]
    step = max(spans) if pressure and np.all(np.isfinite(spans)) else plan.max_increment
    drive = "force" if pressure else "displacement"
    reached = {}
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", OutOfBoundsWarning)
        if pressure:
            result = follow_embedded(
                robot,
                targets,
                EmbeddedController(learned, pid=controller()),
                iterations=iterations,
                closed_loop=bool(gains),
                max_increment=step,
            )
        else:
            result = follow(learned)
    reached["learned"] = result
    if exact:
        # The reference is the W the network learned (the plan's tangent).
        reference = ExactCondensed(robot, StaticSolver(robot, consistent=plan.consistent_tangent))
        reached["exact"] = follow(reference, drive=drive)
    rate = None
    if embedded:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", OutOfBoundsWarning)
            rate = loop_frequency(EmbeddedController(learned, pid=controller()), targets, embedded)
    folder = out / f"{plan.robot}_{name}"
    folder.mkdir(parents=True, exist_ok=True)
    plane = (0, 1) if plan.robot == "diamond" else (0, 2)
    plot = plot_reached(
        targets,
        {k: r.reached[:, 0] for k, r in reached.items()},
        folder / "reached.png",
        plane=plane,
        title=f"{plan.robot} {name}: learned vs exact condensed model",
    )
    report = {
        k: {"errors": r.errors.tolist(), "mean_error": float(r.errors.mean())}
        for k, r in reached.items()
    }
    report["out_of_bounds_warnings"] = len(caught)
    if rate is not None:
        report["embedded_loop_hz"] = rate
    write_json(folder / "report.json", report)
    for k, r in reached.items():
        console.print(f"{k}: mean distance to goal {r.errors.mean():.3f}, max {r.errors.max():.3f}")
    if "exact" in reached:
        gap = np.linalg.norm(reached["learned"].reached - reached["exact"].reached, axis=-1)
        console.print(f"learned vs exact reached positions: mean gap {gap.mean():.3f}")
    if rate is not None:
        console.print(f"embedded loop (network + QP): {rate:.0f} iterations/s")
    console.print(f"saved {plot} and {folder / 'report.json'}")


@app.command()
def calibrate(
    model: Annotated[
        Path, typer.Argument(help="parametric model file (train on a design dataset)")
    ],
    truth: Annotated[
        list[str],
        typer.Option(help="NAME=VALUE of the simulated robot observed, e.g. poisson_ratio=0.47"),
    ],
    start: Annotated[list[str], typer.Option(help="NAME=VALUE initial guesses")],
    fit: Annotated[str, typer.Option(help="parameters fitted, comma separated")] = "poisson_ratio",
    commands: Annotated[
        str, typer.Option(help="displacements of the first actuator observed, comma separated")
    ] = "0,5,10",
    learning_rate: PositiveNumber = 0.01,
    iterations: Count = 300,
    out: OutFolder = Path("out"),
) -> None:
    """Calibrate MODEL to the FEM robot built with TRUTH (Eq. 5.15-5.16, Fig. 5.13).

    The robot's effector is observed at the commands; the parameters FIT descend O_cal from
    START. Writes the history (JSON) and its plot to OUT.
    """
    from pliant.condensed.calibration import calibrate as run_calibration
    from pliant.condensed.calibration import observe
    from pliant.condensed.parametric import ParametricCondensedModel
    from pliant.condensed.plots import plot_calibration

    design = {
        k: numbers_list(v, f"--truth {k}", count=1)[0]
        for k, v in assignments(truth, form="NAME=VALUE").items()
    }
    initial = {
        k: numbers_list(v, f"--start {k}", count=1)[0]
        for k, v in assignments(start, form="NAME=VALUE").items()
    }
    pull = numbers_list(commands, "--commands")
    parametric = ParametricCondensedModel.load(model)
    plan = parametric.plan
    pulls = np.zeros((len(pull), len(plan.actuator_bounds)))
    pulls[:, 0] = pull
    delta_a, observed = observe(plan, design, pulls)
    result = run_calibration(
        parametric,
        delta_a,
        observed,
        {**design, **initial},
        fit=fit.split(","),
        learning_rate=learning_rate,
        iterations=iterations,
    )
    out.mkdir(parents=True, exist_ok=True)
    report = {"truth": design, "start": initial, **dataclasses.asdict(result)}
    write_json(out / "calibration.json", report)
    plot_calibration(
        {"start " + ", ".join(f"{k}={v:g}" for k, v in initial.items()): result.history},
        fit.split(",")[0],
        out / "calibration.png",
        truth=design.get(fit.split(",")[0]),
    )
    fitted = ", ".join(f"{k} = {result.parameters[k]:.4g}" for k in fit.split(","))
    console.print(f"calibrated {fitted} (O_cal {result.objective:.3g}); saved {out}")


@app.command()
def design(
    model: Annotated[
        Path, typer.Argument(help="parametric Finger model (length, height, joint_height)")
    ],
    grid: Annotated[str, option("grid values per design parameter", _widths)] = "10,6,10",
    command: Annotated[str, typer.Option(help="actuator displacements of the pull")] = "10,0",
    weights: Annotated[str, typer.Option(help="gamma_1,gamma_2 of Eq. 5.20")] = "0.5,0.5",
    iterations: Annotated[int, option("gradient steps per refinement", at_least_one)] = 200,
    learning_rate: PositiveNumber = 0.01,
    out: OutFolder = Path("out/design"),
) -> None:
    """Design the parametric Soft Finger with MODEL (Eq. 5.17-5.20, Fig. 5.15-5.17).

    Grid search, gradient refinement of dexterity, strength and their weighted sum,
    landscapes and Pareto front; writes design.json and the plots to OUT.
    """
    from pliant.condensed.design import FingerObjectives, design_study
    from pliant.condensed.parametric import ParametricCondensedModel
    from pliant.condensed.plots import plot_design_study

    gamma = numbers_list(weights, "--weights (dexterity, strength)", count=2)
    pull = tuple(numbers_list(command, "--command"))
    parametric = ParametricCondensedModel.load(model)
    with Progress(console=console, transient=True) as bar:
        bar.add_task("grid search and refinements", total=None)
        study = design_study(
            parametric,
            FingerObjectives(command=pull),
            counts=list(grid),
            weights=(gamma[0], gamma[1]),
            iterations=iterations,
            learning_rate=learning_rate,
        )
    summary = study.summary()
    out.mkdir(parents=True, exist_ok=True)
    write_json(out / "design.json", summary)
    plots = plot_design_study(study, out)
    table = Table(title=f"{len(study.grid)} designs, {int(study.pareto.sum())} on the Pareto front")
    for col in ("objective", *study.names, "value"):
        table.add_column(col)
    for name, r in summary["refined"].items():
        table.add_row(name, *(f"{v:.2f}" for v in r["design"].values()), f"{r['objective']:.4g}")
    console.print(table)
    console.print(f"saved {out / 'design.json'} and {', '.join(p.name for p in plots)}")
