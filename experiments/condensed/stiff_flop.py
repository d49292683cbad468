"""Table 5.4 analogue: the learned condensed model of the Stiff-Flop (pneumatic trunk), its
test loss, and a spiral of 40 goals followed open and closed loop (PID of Eq. 5.14) with
pressure-controlled chambers, learned against exact condensed matrices.

Thesis: 50000 samples, the chambers' volume change sampled in [0, 30] mm^3, test loss 9.22e-4
(best epoch 37070 of 50000). Here each chamber pair's volume change in [0, 100] mm^3: this
Stiff-Flop's chambers are larger than the thesis' model's, and 30 mm^3 moves its tip less than
0.6 mm (0.3 mm of it the sag under gravity); 100 mm^3 is about 0.4 bar in one pair, the tip
about 6 mm off the axis. 4800 training + 1200 test samples (0.24 s of CPU a sample; about
33 minutes on a core shared with two other jobs), then training on one thread (2 minutes) and
the spiral (2 minutes):

    OPENBLAS_NUM_THREADS=1 OMP_NUM_THREADS=1 NUMBA_NUM_THREADS=1 \
        python experiments/condensed/stiff_flop.py --work out/condensed_stiff_flop

The committed results are the thesis' 50 000 samples (40 000 + 10 000 test; 115 minutes of
collection on 2 workers, training 200 epochs on one thread about 10 minutes):

    OPENBLAS_NUM_THREADS=1 OMP_NUM_THREADS=1 NUMBA_NUM_THREADS=1 \
        python experiments/condensed/stiff_flop.py --samples 40000 --epochs 200 --workers 2

The actuators are the six chamber pairs' CavityActuators: delta_a is the volume change
(mm^3), lambda_a the pressure (kPa). The collection imposes volume changes (the generator
imposes actuator displacements); control is in pressure, as on the real robot: the QP's
pressures go to the FEM plant, and the learned model is queried at
delta_a = W_aa lambda_a + delta_a_free, its own prediction of the volumes (no volume sensing).

Datasets, checkpoints and models go to --work (resumable: rerun the same command after an
interruption); the table (JSON) and the trajectory plots (PNG) to --out.
"""

from __future__ import annotations

import json
import warnings
from pathlib import Path
from typing import Annotated

import numpy as np
import typer

from pliant import configure_threads, robots
from pliant.condensed.collect import load_or_collect
from pliant.condensed.control import (
    PID,
    EmbeddedController,
    ExactCondensed,
    TrajectoryResult,
    follow_embedded,
    follow_trajectory,
)
from pliant.condensed.dataset import CollectionPlan
from pliant.condensed.learned import LearnedCondensedModel, OutOfBoundsWarning
from pliant.condensed.plots import plot_history, plot_reached
from pliant.condensed.train import TrainConfig, evaluate, train_condensed
from pliant.solvers import StaticSolver

THESIS = {"samples": 50000, "test_loss": 9.22e-4, "best_epoch": 37070, "epochs": 50000}
VOLUME_BOUNDS = (0.0, 100.0)  # mm^3, each chamber pair (thesis: 0-30)
PRESSURE_STEP = 60.0  # kPa: the plant's force load steps (the whole 0-0.6 bar at once)


def plan(samples: int) -> CollectionPlan:
    """The collection: every chamber's volume change in VOLUME_BOUNDS, each sample reached
    in one static step from the previous one where Newton converges (the whole box is one
    increment). W of the consistent tangent, with the pressure's load stiffness: the
    compliance to a change of pressure (SOFA's material tangent, the thesis' W, misses 4 % of
    the tip's motion per kPa on a coarse PneuNet)."""
    return CollectionPlan(
        "stiff_flop",
        (VOLUME_BOUNDS,) * 6,
        samples,
        max_increment=VOLUME_BOUNDS[1],
        consistent_tangent=True,
    )


def track(
    learned: LearnedCondensedModel,
    goals: np.ndarray,
    source: str,
    pid: list[float] | None,
    iterations: int,
) -> TrajectoryResult:
    """The FEM Stiff-Flop, pressure-controlled, through `goals`: by Algorithm 2 on the
    learned model (its own volumes, no sensing), or by the same QP on the FEM's W at the
    plant's state (`source` "exact"); closed loop with the PID of Eq. 5.14 if `pid`."""
    fem = robots.build("stiff_flop", **learned.plan.robot_kwargs)
    if source == "exact":
        exact = ExactCondensed(fem, StaticSolver(fem, consistent=learned.plan.consistent_tangent))
        return follow_trajectory(
            fem,
            goals,
            exact,
            iterations=iterations,
            pid=PID(*pid) if pid else None,
            course=learned.input_box,
            max_increment=PRESSURE_STEP,
            drive="force",
        )
    controller = EmbeddedController(learned, pid=PID(*pid) if pid else None)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", OutOfBoundsWarning)  # it starts at the rest volumes
        return follow_embedded(
            fem,
            goals,
            controller,
            iterations=iterations,
            closed_loop=pid is not None,
            max_increment=PRESSURE_STEP,
        )


def main(
    samples: Annotated[int, typer.Option(help="training samples (test: a quarter more)")] = 4800,
    epochs: Annotated[int, typer.Option()] = 800,
    learning_rate: Annotated[float, typer.Option()] = 1e-3,
    batch_size: Annotated[int, typer.Option()] = 64,
    iterations: Annotated[int, typer.Option(help="control iterations per goal")] = 2,
    n_goals: Annotated[int, typer.Option("--goals", help="goals of the spiral")] = 40,
    pid: Annotated[str, typer.Option(help="K,I,D of the closed loop")] = "0.5,0.1,0",
    workers: Annotated[int, typer.Option()] = 1,
    work: Annotated[Path, typer.Option(help="datasets, checkpoints, models")] = Path(
        "out/condensed_stiff_flop"
    ),
    out: Annotated[Path, typer.Option(help="results")] = Path("experiments/results/condensed"),
) -> None:
    configure_threads(torch_threads=1)
    out.mkdir(parents=True, exist_ok=True)
    work.mkdir(parents=True, exist_ok=True)
    the_plan = plan(samples)
    dataset = load_or_collect(the_plan, work / f"stiff_flop_{samples}.h5", workers=workers)
    model_path = work / f"stiff_flop_{samples}.pt"
    if model_path.exists():
        learned = LearnedCondensedModel.load(model_path)
    else:
        config = TrainConfig(
            epochs=epochs,
            learning_rate=learning_rate,
            batch_size=batch_size,
            checkpoint=work / f"stiff_flop_{samples}.ckpt",
            progress=False,
        )
        learned, result = train_condensed(dataset, config)
        learned.save(model_path)
        plot_history(
            result.history,
            out / "table_5_4_stiff_flop_training.png",
            title=f"Stiff-Flop: F on {samples} samples",
        )
    scores = evaluate(learned, dataset.test)
    failed = sum(int((~s.converged.astype(bool)).sum()) for s in (dataset.train, dataset.test))
    clipped = float(
        max(np.nanmax(np.abs(s.delta_a - s.command)) for s in (dataset.train, dataset.test))
    )
    report = {
        "samples": samples,
        "test_samples": the_plan.n_test,
        "volume_bounds_mm3": list(VOLUME_BOUNDS),
        "failed_samples": failed,
        "largest_volume_short_of_command_mm3": clipped,
        "test_loss": scores["loss"],
        "constant_w0_baseline": scores["baseline_loss"],
        "best_epoch": learned.training["best_epoch"],
        "epochs": epochs,
        "learning_rate": learning_rate,
        "thesis": THESIS,
    }
    print(json.dumps(report))
    goals = robots.entry("stiff_flop").trajectories["spiral"](n_goals)
    gains = [float(v) for v in pid.split(",")]
    for loop, loop_pid in (("open", None), ("closed", gains)):
        reached = {}
        for source in ("learned", "exact"):
            cache = work / f"spiral{n_goals}_{loop}_{source}_{samples}_{iterations}.npz"
            if cache.exists():
                with np.load(cache) as data:
                    reached[source] = TrajectoryResult(**{k: data[k] for k in data.files})
                continue
            reached[source] = track(learned, goals, source, loop_pid, iterations)
            np.savez(cache, **vars(reached[source]))
        d = {k: float(r.errors.mean()) for k, r in reached.items()}
        gap = np.linalg.norm(reached["learned"].reached - reached["exact"].reached, axis=-1)
        report[loop] = {
            "mean_distance_to_goal_mm": d,
            "max_distance_to_goal_mm": {k: float(r.errors.max()) for k, r in reached.items()},
            "table_5_8_error": abs(d["exact"] - d["learned"]) / d["exact"],
            "learned_vs_exact_gap_mean_mm": float(gap.mean()),
            "learned_vs_exact_gap_max_mm": float(gap.max()),
        }
        plot_reached(
            goals,
            {k: r.reached[:, 0] for k, r in reached.items()},
            out / f"trajectory_stiff_flop_spiral_{loop}.png",
            title=f"Stiff-Flop spiral ({n_goals} goals), {loop} loop, pressure control",
        )
        print(loop, json.dumps(report[loop]))
    report["settings"] = {
        "iterations_per_goal": iterations,
        "pid": pid,
        "spiral": f"{n_goals} goals, radius 0.18 to 1.8 mm in 2 turns, z = 99.71 mm",
        "units": "mm, mm^3, kPa",
    }
    report["note"] = (
        f"{samples} training samples (thesis 50000), volume change 0-100 mm^3 per chamber pair"
        " (thesis 0-30: this model's chambers are larger; 30 mm^3 moves its tip < 0.6 mm)."
        " Learned: Algorithm 2 on the network, pressures to the FEM, volumes predicted. Exact:"
        " the same QP on the FEM's W (consistent tangent, with the pressure's load stiffness) at"
        " the plant's state."
    )
    (out / "table_5_4_stiff_flop.json").write_text(json.dumps(report, indent=1))


if __name__ == "__main__":
    typer.run(main)
