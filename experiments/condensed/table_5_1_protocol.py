"""Table 5.1's Diamond under a protocol a reviewer accepts (issue #61, item 4): everything chosen
on a validation set, the test loss reported on a held-out test set drawn afterwards.

The committed Diamond figures (table_5_1.py, table_5_1_corner.py) chose the epoch of least
loss on the very test set they report, and the corner box (all cables 24-30 mm) was declared
after looking at the uniform model's worst test sample. Here:

* validation: the 1625 random samples the earlier runs tested on (the uniform dataset's test
  split, seed 0): the epochs are chosen on it, and so is the corner box;
* test: 1625 new random samples of the same box, the test stream of seed 1 (``--test-seed``),
  solved after the choices and read only for the figures;
* the corner box, by a rule declared before any test loss: the box of width ``--corner-width``
  (6 mm, a fifth of the 30 mm range) at the vertex of the sampled box nearest the worst
  validation sample of the uniform model (a cable above mid-range: its top 6 mm, else its
  bottom 6 mm); ``--corner-samples`` samples there (Halton, actuated from rest, seed 7);
* both networks trained as table_5_1.py trains the Diamond (SiLU 3 x 450, one cosine cycle
  peaking at 2e-3, batches of 256): the uniform one on the 6500 uniform samples (3000 epochs),
  the corner one on the first 6200 uniform samples and the corner's (the thesis' count, 1500
  epochs).

Needs the uniform dataset of table_5_1.py (collected first, 16 min on two quiet cores):

    OPENBLAS_NUM_THREADS=1 OMP_NUM_THREADS=1 NUMBA_NUM_THREADS=1 \\
        python experiments/condensed/table_5_1.py --robot diamond --workers 2 \\
        --work out/condensed_full
    python experiments/condensed/table_5_1_protocol.py --workers 2   # about 35 min more

Writes table_5_1_diamond_protocol.json (old and new figures) to --out and the two networks to
--work (diamond_protocol_uniform.pt, diamond_protocol_corner.pt). The two networks are kept in
experiments/results/condensed/table_5_1_models; ``--evaluate`` re-scores them from the
repository alone (the held-out samples solved again by the FEM from the plan the models record:
1617 converged of 1625 solves, 18 min on the shared machine):

    python experiments/condensed/table_5_1_protocol.py --evaluate \
        experiments/results/condensed/table_5_1_models --out /tmp/t51
"""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path
from typing import Annotated

import numpy as np
import torch
import typer

from pliant import configure_threads
from pliant.condensed.collect import held_out_split, load_or_collect
from pliant.condensed.dataset import Dataset, Split
from pliant.condensed.learned import LearnedCondensedModel
from pliant.condensed.networks import StandardisedMLP
from pliant.condensed.train import TrainConfig, fit, loss_spread, sample_losses

TRAINING = TrainConfig(
    batch_size=256, learning_rate=2e-3, activation="silu", schedule="cosine", progress=False
)
OLD = {  # the committed figures, chosen and reported on the validation set used here
    "uniform": ("experiments/results/condensed/table_5_1.json", "diamond"),
    "corner": ("experiments/results/condensed/table_5_1_diamond_6495.json", None),
}


def _tensor(array: np.ndarray) -> torch.Tensor:
    return torch.from_numpy(np.ascontiguousarray(array, dtype=np.float32))


def corner_box(worst: np.ndarray, box: tuple[tuple[float, float], ...], width: float):
    """The box of `width` at the vertex of `box` nearest the point `worst` (per cable: the top
    `width` where `worst` lies above mid-range, else the bottom)."""
    return tuple(
        (hi - width, hi) if value > 0.5 * (lo + hi) else (lo, lo + width)
        for value, (lo, hi) in zip(worst, box, strict=True)
    )


def train(data: Split, validation: Split, epochs: int, checkpoint: Path) -> tuple:
    """A network trained on `data`, its epoch chosen on `validation`; its row."""
    x, y = _tensor(data.inputs()), _tensor(data.outputs())
    config = replace(TRAINING, epochs=epochs, checkpoint=checkpoint)
    torch.manual_seed(config.seed)
    network = StandardisedMLP(x, y, hidden=config.hidden, activation=config.activation)
    valid = (_tensor(validation.inputs()), _tensor(validation.outputs()))
    result = fit(network, (x, y), valid, config)
    return network, {
        "training_samples": len(data),
        "best_epoch_on_validation": result.best_epoch,
        "epochs": epochs,
        "validation_loss": result.best_test_loss,
    }


def scores(network: StandardisedMLP, test: Split) -> dict:
    """The test loss (Eq. 5.5) and its spread over the samples, under this study's names."""
    spread = loss_spread(network, test)
    return {
        "test_loss": spread["loss"],
        "median_test_sample_loss": spread["median_sample_loss"],
        "worst_test_sample_share": spread["worst_sample_share"],
    }


def evaluate_kept(folder: Path, test_seed: int, workers: int, out: Path) -> None:
    """The kept networks scored on the held-out samples solved again (--evaluate)."""
    models = {
        key: LearnedCondensedModel.load(folder / f"diamond_protocol_{key}.pt")
        for key in ("uniform", "corner")
    }
    test = held_out_split(models["uniform"].plan, test_seed, workers=workers)
    report = {
        "test_samples": len(test),
        **{key: scores(model.network, test) for key, model in models.items()},
    }
    out.mkdir(parents=True, exist_ok=True)
    (out / "table_5_1_diamond_protocol.json").write_text(json.dumps(report, indent=1))
    print(json.dumps(report, indent=1))


def main(
    samples: Annotated[int, typer.Option(help="the uniform dataset's training samples")] = 6500,
    corner_samples: Annotated[int, typer.Option()] = 300,
    corner_width: Annotated[float, typer.Option(help="mm")] = 6.0,
    uniform_for_corner: Annotated[int, typer.Option(help="uniform samples beside them")] = 6200,
    epochs: Annotated[int, typer.Option(help="the uniform network's")] = 3000,
    corner_epochs: Annotated[int, typer.Option()] = 1500,
    test_seed: Annotated[int, typer.Option(help="seed of the held-out test draw")] = 1,
    workers: Annotated[int, typer.Option()] = 1,
    work: Annotated[Path, typer.Option(help="datasets, checkpoints")] = Path("out/condensed_full"),
    out: Annotated[Path, typer.Option(help="results")] = Path("experiments/results/condensed"),
    evaluate: Annotated[
        Path | None,
        typer.Option(help="a folder of the kept networks: re-score them on the test draw, exit"),
    ] = None,
) -> None:
    configure_threads(torch_threads=1)
    if evaluate is not None:
        evaluate_kept(evaluate, test_seed, workers, out)
        return
    uniform = Dataset.load(work / f"diamond_{samples}.h5")
    validation = uniform.test.converged_only()
    uniform_train = uniform.train.converged_only()
    first, uniform_row = train(uniform_train, validation, epochs, work / "protocol_uniform.ckpt")
    # The corner box from the validation set alone, before any held-out sample is solved.
    worst = validation.delta_a[int(np.argmax(sample_losses(first, validation)))]
    box = corner_box(worst, uniform.plan.actuator_bounds, corner_width)
    # The uniform plan's robot and solver (each sample from rest, SOFA's W) in the corner box.
    corner_plan = replace(
        uniform.plan, actuator_bounds=box, n_train=corner_samples, test_fraction=0.0, seed=7
    )
    name = f"diamond_corner_{corner_samples}_" + "_".join(f"{lo:g}-{hi:g}" for lo, hi in box)
    corner = load_or_collect(corner_plan, work / f"{name}.h5", workers=workers)
    both = Split.concatenate(
        [uniform_train.head(uniform_for_corner), corner.train.converged_only()]
    )
    second, corner_row = train(both, validation, corner_epochs, work / f"protocol_{name}.ckpt")
    # The held-out test set, drawn only now: the test stream of another seed, same box.
    test = held_out_split(uniform.plan, test_seed, workers=workers)
    for key, network in (("uniform", first), ("corner", second)):
        LearnedCondensedModel.from_dataset(network, uniform, {"selected_on": "validation"}).save(
            work / f"diamond_protocol_{key}.pt"
        )
    old = {}
    for key, (path, row) in OLD.items():
        data = json.loads(Path(path).read_text()) if Path(path).is_file() else {}
        old[key] = (data.get(row) if row else data) or {}
    report = {
        "protocol": "epochs and the corner box chosen on the validation set (the"
        f" {len(validation)} random samples earlier runs tested on); test loss on"
        f" {len(test)} random samples drawn afterwards (test stream of seed {test_seed})",
        "validation_samples": len(validation),
        "test_samples": len(test),
        "worst_validation_sample_mm": worst.round(2).tolist(),
        "corner_box_mm": [list(b) for b in box],
        "uniform": uniform_row | scores(first, test),
        "corner": corner_row
        | scores(second, test)
        | {"corner_samples": len(corner.train.converged_only())},
        "old": {
            key: {"test_loss": row.get("test_loss"), "selected_on": "the test set reported"}
            for key, row in old.items()
        },
        "thesis": {"samples": 6500, "test_loss": 6.52e-5},
    }
    out.mkdir(parents=True, exist_ok=True)
    (out / "table_5_1_diamond_protocol.json").write_text(json.dumps(report, indent=1))
    print(json.dumps(report, indent=1))


if __name__ == "__main__":
    typer.run(main)
