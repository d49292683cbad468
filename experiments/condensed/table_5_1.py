"""Table 5.1 analogue: standardised test loss and best epoch of F for the Diamond and the Finger.

Thesis: 6500 samples, Diamond cables 0-30 mm -> 6.52e-5 (best epoch 8960), Finger 0-20 mm ->
3.79e-6 (8850), 9000 epochs at a learning rate of 1e-4. Here the thesis' 6500 samples (and
1625 test samples), each robot with its own training (TRAINING below; the options override
both):

    OPENBLAS_NUM_THREADS=1 OMP_NUM_THREADS=1 NUMBA_NUM_THREADS=1 \
        python experiments/condensed/table_5_1.py --workers 2 --work out/condensed_full

* Finger: ReLU, 1500 epochs at 1e-3 halved on plateaus of the training loss, batches of 64
  (about 25 minutes on one core).
* Diamond: SiLU, 3000 epochs of one cosine cycle peaking at 2e-3, batches of 256 (about 20
  minutes on one core; collection 16 minutes on two). With ReLU and the Finger's schedule the
  same data give 1.66e-4 (best epoch 1389 of 1500): a piecewise-linear F fits the smooth
  compliances less closely (docs/condensed.md).

Each Diamond sample is actuated from rest (CollectionPlan's ``start="rest"``): its arms,
compressed by antagonist cables, have several equilibria for one command, and load-stepping
from the previous sample's equilibrium (the collection's default) put some samples on another
branch; on such data the test loss stopped at 3.6e-4, the worst 1 % of the test samples making
75 % of it.

W is SOFA's material-tangent compliance, the thesis' W; the equilibria are solved on the
consistent tangent. Ranges: the Diamond's cables 0-30 mm, the thesis' range (the cables are
allowed 30 mm). The Finger's cables -10..10 mm: its cables at 0.4 height from the mid-plane
bend it much more per millimetre than the thesis' (cable 0 at 10 mm, cable 1 held at its
length, moves the tip 33 mm down; the thesis' closing trajectory spans 30 mm), and a negative
command lets the antagonist cable pay out instead of holding the finger.

Protocol (issue #61): the epoch is chosen on the dataset's test split, which is therefore a
validation set; each row's ``held_out`` is the test loss on a test set drawn afterwards (the
test stream of seed ``--held-out-seed``, same box and count), solved only once the network is
chosen. ``test_loss`` and ``best_epoch`` are the validation figures the table reported before.
The Finger's network is kept in experiments/results/condensed/table_5_1_models; ``--evaluate``
re-scores the kept networks there on the held-out draw from the repository alone (the samples
solved again by the FEM from the plan each model records):

    python experiments/condensed/table_5_1.py --evaluate \
        experiments/results/condensed/table_5_1_models --robot finger --out /tmp/t51

Datasets, checkpoints and models go to --work (resumable: rerun the same command after an
interruption); the table (JSON, one row per robot, the rows of robots not run kept) and the
training curves (PNG) to --out. Each row also gives the spread of the test loss over the
samples (median, and the share of the worst sample).
"""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path
from typing import Annotated

import numpy as np
import typer

from pliant.condensed.collect import load_or_collect
from pliant.condensed.dataset import CollectionPlan
from pliant.condensed.learned import LearnedCondensedModel
from pliant.condensed.plots import plot_history
from pliant.condensed.train import (
    TrainConfig,
    evaluate,
    sample_losses,
    score_held_out,
    train_condensed,
)

THESIS = {"diamond": (6.52e-5, 8960), "finger": (3.79e-6, 8850)}
BOUNDS = {"diamond": ((0.0, 30.0),) * 4, "finger": ((-10.0, 10.0),) * 2}
# The Diamond's cables may reach the sampled 30 mm (SoftRobots' inverse scene stops at 20).
ROBOT_KWARGS = {"diamond": {"max_cable_displacement": 30.0}, "finger": {}}
# Each Diamond sample is actuated from rest (module docstring).
START = {"diamond": "rest", "finger": "previous"}
TRAINING = {
    "finger": TrainConfig(epochs=1500, learning_rate=1e-3, batch_size=64, progress=False),
    "diamond": TrainConfig(
        epochs=3000,
        learning_rate=2e-3,
        batch_size=256,
        activation="silu",
        schedule="cosine",
        progress=False,
    ),
}


def evaluate_kept(folder: Path, robots, seed: int, workers: int, out: Path) -> None:
    """--evaluate: the kept networks (``{robot}.pt`` in `folder`) on the held-out draw."""
    models = {robot: LearnedCondensedModel.load(folder / f"{robot}.pt") for robot in robots}
    rows = {
        robot: {"held_out": score_held_out(model, seed, workers=workers)}
        for robot, model in models.items()
    }
    out.mkdir(parents=True, exist_ok=True)
    (out / "table_5_1.json").write_text(json.dumps(rows, indent=1))
    print(json.dumps(rows, indent=1))


def main(
    finger_samples: Annotated[int, typer.Option()] = 6500,
    diamond_samples: Annotated[int, typer.Option()] = 6500,
    epochs: Annotated[int | None, typer.Option(help="override both robots'")] = None,
    learning_rate: Annotated[float | None, typer.Option()] = None,
    batch_size: Annotated[int | None, typer.Option()] = None,
    activation: Annotated[str | None, typer.Option(help="relu, silu or tanh")] = None,
    schedule: Annotated[str | None, typer.Option(help="plateau or cosine")] = None,
    workers: Annotated[int, typer.Option()] = 1,
    work: Annotated[Path, typer.Option(help="datasets, checkpoints, models")] = Path(
        "out/condensed"
    ),
    out: Annotated[Path, typer.Option(help="results")] = Path("experiments/results/condensed"),
    robot_names: Annotated[
        list[str], typer.Option("--robot", help="robots to run (default: both)")
    ] = ("finger", "diamond"),
    held_out_seed: Annotated[int, typer.Option(help="seed of the held-out test draw")] = 1,
    evaluate_folder: Annotated[
        Path | None,
        typer.Option("--evaluate", help="a folder of kept networks: re-score them, exit"),
    ] = None,
) -> None:
    if evaluate_folder is not None:
        evaluate_kept(evaluate_folder, robot_names, held_out_seed, workers, out)
        return
    out.mkdir(parents=True, exist_ok=True)
    path = out / "table_5_1.json"
    rows = json.loads(path.read_text()) if path.is_file() else {}
    sizes = {"finger": finger_samples, "diamond": diamond_samples}
    overrides = {
        "epochs": epochs,
        "learning_rate": learning_rate,
        "batch_size": batch_size,
        "activation": activation,
        "schedule": schedule,
    }
    for robot in robot_names:
        samples = sizes[robot]
        # W of SOFA's material tangent, the thesis' W (equilibria solved on the consistent
        # one): where the Diamond's held cables stabilise compressed arms, the consistent K is
        # near singular and its W reaches 10^4 times its median, off any learnable trend.
        plan = CollectionPlan(
            robot,
            BOUNDS[robot],
            samples,
            robot_kwargs=ROBOT_KWARGS[robot],
            consistent_tangent=False,
            start=START[robot],
        )
        dataset = load_or_collect(plan, work / f"{robot}_{samples}.h5", workers=workers)
        config = replace(
            TRAINING[robot],
            checkpoint=work / f"{robot}_{samples}.ckpt",
            **{k: v for k, v in overrides.items() if v is not None},
        )
        learned, result = train_condensed(dataset, config)
        learned.training["selected_on"] = "validation"
        learned.save(work / f"{robot}_{samples}.pt")
        scores = evaluate(learned, dataset.test)
        per_sample = sample_losses(learned.network, dataset.test)
        worst = int(np.argmax(per_sample))
        plot_history(
            result.history,
            out / f"table_5_1_{robot}_training.png",
            title=f"{robot}: F on {samples} samples",
        )
        rows[robot] = {
            "samples": samples,
            "test_samples": plan.n_test,
            "bounds_mm": list(BOUNDS[robot][0]),
            "start": plan.start,
            "failed_samples": int((~dataset.train.converged.astype(bool)).sum())
            + int((~dataset.test.converged.astype(bool)).sum()),
            "test_loss": scores["loss"],
            "constant_w0_baseline": scores["baseline_loss"],
            "median_sample_loss": float(np.median(per_sample)),
            "worst_sample": {
                "delta_a_mm": dataset.test.converged_only().delta_a[worst].round(2).tolist(),
                "loss": float(per_sample[worst]),
                "share_of_test_loss": float(per_sample[worst] / per_sample.sum()),
            },
            "test_loss_without_worst_sample": float(np.delete(per_sample, worst).mean()),
            # The epoch was chosen on the test split above, a validation set: held_out is the
            # protocol's figure, on samples drawn after the choice.
            "selected_on": "test split (validation)",
            "held_out": score_held_out(learned, held_out_seed, workers=workers),
            "best_epoch": result.best_epoch,
            "epochs": config.epochs,
            "learning_rate": config.learning_rate,
            "batch_size": config.batch_size,
            "activation": config.activation,
            "schedule": config.schedule,
            "hidden": list(config.hidden),
            "thesis_samples": 6500,
            "thesis_epochs": 9000,
            "thesis_test_loss": THESIS[robot][0],
            "thesis_best_epoch": THESIS[robot][1],
        }
        print(robot, json.dumps(rows[robot]))
        path.write_text(json.dumps(rows, indent=1))
    rows["note"] = (
        "Standardised test losses (Eq. 5.5) at the best epoch; 6500 training samples (thesis"
        " 6500), each robot's training in its row (thesis: 9000 epochs at 1e-4). Diamond"
        " cables 0-30 mm, the thesis' range, each sample actuated from rest. W of SOFA's"
        " material tangent, the thesis' W; equilibria solved on the consistent tangent."
        " Finger cables -10..10 mm: its cables, 0.4 height from the mid-plane, move the tip"
        " 33 mm down at 10 mm (the thesis' closing trajectory spans 30 mm); a negative command"
        " lets the antagonist cable go slack."
    )
    path.write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    typer.run(main)
