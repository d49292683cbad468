"""Table 5.2 analogue: F's test loss and the embedded control-loop rate for the three Finger
meshes (coarse ~1.5k, fine ~9k, superfine ~18k tetrahedra).

Thesis: losses 3.79e-6 / 4.26e-6 / 3.60e-6 and ~300 FPS with the learned model whatever the
mesh. Target here: >= 3000 loop iterations/s (network + QP, Algorithm 2), independent of the
mesh, since the network's size does not depend on it.

    python experiments/condensed/table_5_2.py --samples 6500 --epochs 9000
    python experiments/condensed/table_5_2.py --samples 32 --epochs 100 --bound 4 \
        --resolutions coarse
"""

from __future__ import annotations

import json
import warnings
from pathlib import Path
from typing import Annotated

import typer

from pliant import robots
from pliant.condensed.collect import collect
from pliant.condensed.control import EmbeddedController, loop_frequency
from pliant.condensed.dataset import CollectionPlan, Dataset
from pliant.condensed.learned import OutOfBoundsWarning
from pliant.condensed.train import TrainConfig, evaluate, train_condensed

THESIS = {"coarse": (3.79e-6, 308.6), "fine": (4.26e-6, 334.4), "superfine": (3.60e-6, 296.7)}


def main(
    samples: Annotated[int, typer.Option()] = 6500,
    epochs: Annotated[int, typer.Option()] = 9000,
    bound: Annotated[float, typer.Option(help="cables 0..this mm")] = 20.0,
    resolutions: Annotated[str, typer.Option()] = "coarse,fine,superfine",
    iterations: Annotated[int, typer.Option(help="timed loop iterations")] = 5000,
    workers: Annotated[int, typer.Option()] = 1,
    out: Annotated[Path, typer.Option()] = Path("experiments/condensed/results"),
) -> None:
    rows = {}
    goals = robots.entry("finger").trajectories["closing"](25)
    for resolution in resolutions.split(","):
        plan = CollectionPlan(
            "finger", ((0.0, bound),) * 2, samples, robot_kwargs={"resolution": resolution}
        )
        path = out / f"finger_{resolution}_{samples}.h5"
        dataset = Dataset.load(path) if path.exists() else collect(plan, path, workers=workers)
        learned, result = train_condensed(
            dataset, TrainConfig(epochs=epochs, checkpoint=path.with_suffix(".ckpt"))
        )
        learned.save(path.with_suffix(".pt"))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", OutOfBoundsWarning)
            rate = loop_frequency(EmbeddedController(learned), goals, iterations)
        rows[resolution] = {
            "tetrahedra": robots.build("finger", resolution=resolution).body.mesh.n_tets,
            "test_loss": evaluate(learned, dataset.test)["loss"],
            "best_epoch": result.best_epoch,
            "loop_hz": rate,
            "thesis_test_loss": THESIS[resolution][0],
            "thesis_fps": THESIS[resolution][1],
        }
        print(resolution, json.dumps(rows[resolution]))
    (out / f"table_5_2_{samples}.json").write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    typer.run(main)
