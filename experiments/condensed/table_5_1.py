"""Table 5.1 analogue: standardised test loss and best epoch of F for the Diamond and the Finger.

Thesis: 6500 samples, Diamond cables 0-30 mm -> 6.52e-5 (best epoch 8960), Finger 0-20 mm ->
3.79e-6 (8850), 9000 epochs. The full run is hours of static solves and training on two cores;
`--samples` and `--epochs` give a smaller version.

    python experiments/condensed/table_5_1.py --samples 6500 --epochs 9000
    python experiments/condensed/table_5_1.py --samples 64 --epochs 200 \
        --finger-bound 4 --diamond-bound 4

The same, robot by robot, from the command line:

    pliant condensed collect finger --bounds 0:20 --samples 6500 --out finger.h5
    pliant condensed train finger.h5 --epochs 9000 --out finger.pt --log-dir tb/finger
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer

from pliant.condensed.collect import collect
from pliant.condensed.dataset import CollectionPlan, Dataset
from pliant.condensed.train import TrainConfig, evaluate, train_condensed

THESIS = {"diamond": (6.52e-5, 8960), "finger": (3.79e-6, 8850)}


def main(
    samples: Annotated[int, typer.Option()] = 6500,
    epochs: Annotated[int, typer.Option()] = 9000,
    diamond_bound: Annotated[float, typer.Option(help="Diamond cables 0..this mm")] = 30.0,
    finger_bound: Annotated[float, typer.Option(help="Finger cables 0..this mm")] = 20.0,
    workers: Annotated[int, typer.Option()] = 1,
    out: Annotated[Path, typer.Option()] = Path("experiments/condensed/results"),
) -> None:
    rows = {}
    for robot, bound, n_act in (("diamond", diamond_bound, 4), ("finger", finger_bound, 2)):
        plan = CollectionPlan(robot, ((0.0, bound),) * n_act, samples)
        path = out / f"{robot}_{samples}.h5"
        dataset = Dataset.load(path) if path.exists() else collect(plan, path, workers=workers)
        config = TrainConfig(
            epochs=epochs, checkpoint=out / f"{robot}_{samples}.ckpt", log_dir=out / "tb" / robot
        )
        learned, result = train_condensed(dataset, config)
        learned.save(out / f"{robot}_{samples}.pt")
        scores = evaluate(learned, dataset.test)
        rows[robot] = {
            "samples": samples,
            "bounds_mm": [0.0, bound],
            "failed_samples": int((~dataset.train.converged.astype(bool)).sum()),
            "test_loss": scores["loss"],
            "constant_w0_baseline": scores["baseline_loss"],
            "best_epoch": result.best_epoch,
            "epochs": epochs,
            "thesis_test_loss": THESIS[robot][0],
            "thesis_best_epoch": THESIS[robot][1],
        }
        print(robot, json.dumps(rows[robot]))
    (out / f"table_5_1_{samples}.json").write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    typer.run(main)
