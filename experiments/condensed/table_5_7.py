"""Table 5.7 analogue: test losses of G (design -> W0, delta0_free) and F on the Finger's
mechanical-parameter and geometric datasets.

Thesis: mechanical parameters, Young's modulus 1000-10000 kPa and Poisson ratio 0.400-0.499,
10000 samples -> G 3.82e-7 (best epoch 18420), F 5.04e-5 (12530); geometry (Length 38-42,
Height 20-22, Joint Height 5-8 mm, Table 5.6), 50000 samples, MLP 5 x 800 with dropout 0.4
-> G 0.19 (4400), F 0.13 (270). Here the same boxes (cable 0 pulled 0-10 mm, cable 1 held,
as calibration.py and design.py), every sample its own design. Mechanical: the thesis' 10000
training samples + 2500 test (78 minutes of collection on one shared core, 0.37 s a sample),
SiLU and one cosine cycle (F 1000 epochs, 7 minutes; G 10000, 4 minutes; one thread).
Geometric: the thesis' 50000 + 12500 test samples, each its own design and mesh (collected on
2 worker processes, about 28 chunks of 16 samples a minute on 2 idle cores, resumable), SiLU
and one cosine cycle, 60 epochs each (the 5 x 800 networks about 14 minutes each, one thread):

    export OPENBLAS_NUM_THREADS=1 OMP_NUM_THREADS=1 NUMBA_NUM_THREADS=1
    python experiments/condensed/table_5_7.py --dataset mechanical --samples 10000 \
        --epochs 1000 --design-epochs 10000 --batch-size 256 --learning-rate 2e-3 \
        --activation silu --schedule cosine
    python experiments/condensed/table_5_7.py --dataset geometric --samples 50000 \
        --epochs 60 --design-epochs 60 --batch-size 256 --learning-rate 2e-3 \
        --activation silu --schedule cosine --workers 2

Networks: mechanical, F 3 x 450 and G 2 x 64 (calibration.py's; G maps two parameters);
geometric, both 5 x 800 with dropout 0.4, the thesis'. Datasets, checkpoints and models go
to --work (resumable: rerun the same command after an interruption); the table (JSON) and the
training curves (PNG) to --out.
"""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path
from typing import Annotated

import typer

from pliant import configure_threads
from pliant.condensed.collect import load_or_collect
from pliant.condensed.dataset import CollectionPlan
from pliant.condensed.parametric import train_parametric
from pliant.condensed.plots import plot_history
from pliant.condensed.train import TrainConfig

GEOMETRY = {"length": (38.0, 42.0), "height": (20.0, 22.0), "joint_height": (5.0, 8.0)}

DATASETS = {
    "mechanical": {
        "design_bounds": {"young_modulus": (1000.0, 10000.0), "poisson_ratio": (0.4, 0.499)},
        "f_hidden": (450, 450, 450),
        "g_hidden": (64, 64),
        "dropout": 0.0,
        "thesis": {
            "samples": 10000,
            "g_test_loss": 3.82e-7,
            "g_best_epoch": 18420,
            "f_test_loss": 5.04e-5,
            "f_best_epoch": 12530,
        },
    },
    "geometric": {
        "design_bounds": GEOMETRY,
        "f_hidden": (800,) * 5,
        "g_hidden": (800,) * 5,
        "dropout": 0.4,
        "thesis": {
            "samples": 50000,
            "g_test_loss": 0.19,
            "g_best_epoch": 4400,
            "f_test_loss": 0.13,
            "f_best_epoch": 270,
        },
    },
}


def main(
    samples: Annotated[int, typer.Option(help="training samples per dataset")] = 480,
    epochs: Annotated[int, typer.Option()] = 1000,
    design_epochs: Annotated[int, typer.Option(help="G's epochs (default: --epochs)")] = 0,
    learning_rate: Annotated[float, typer.Option()] = 1e-3,
    batch_size: Annotated[int, typer.Option()] = 32,
    activation: Annotated[str, typer.Option(help="relu, silu or tanh (F and G)")] = "relu",
    schedule: Annotated[str, typer.Option(help="plateau or cosine (F and G)")] = "plateau",
    workers: Annotated[int, typer.Option()] = 1,
    threads: Annotated[int, typer.Option(help="PyTorch threads for the training")] = 1,
    work: Annotated[Path, typer.Option(help="datasets, checkpoints, models")] = Path(
        "out/condensed_table_5_7"
    ),
    out: Annotated[Path, typer.Option(help="results")] = Path("experiments/results/condensed"),
    names: Annotated[
        list[str], typer.Option("--dataset", help="datasets to run (default: both)")
    ] = ("mechanical", "geometric"),
) -> None:
    configure_threads(torch_threads=threads)
    out.mkdir(parents=True, exist_ok=True)
    work.mkdir(parents=True, exist_ok=True)
    path = out / "table_5_7.json"
    report = json.loads(path.read_text()) if path.is_file() else {}
    for name in names:
        spec = DATASETS[name]
        plan = CollectionPlan(
            "finger", ((0.0, 10.0), (0.0, 0.0)), samples, design_bounds=spec["design_bounds"]
        )
        data_path = work / f"finger_{name}_{samples}.h5"
        dataset = load_or_collect(plan, data_path, workers=workers)
        base = TrainConfig(
            epochs=epochs,
            learning_rate=learning_rate,
            batch_size=batch_size,
            dropout=spec["dropout"],
            activation=activation,
            schedule=schedule,
            progress=False,
        )
        model, fits = train_parametric(
            dataset,
            replace(base, hidden=spec["f_hidden"], checkpoint=data_path.with_suffix(".f.ckpt")),
            replace(
                base,
                epochs=design_epochs or epochs,
                hidden=spec["g_hidden"],
                checkpoint=data_path.with_suffix(".g.ckpt"),
            ),
        )
        model.save(data_path.with_suffix(".pt"))
        for network, fit in (("f", fits.condensed), ("g", fits.design)):
            plot_history(
                fit.history,
                out / f"table_5_7_{name}_{network}_training.png",
                title=f"Finger {name}: {network.upper()} on {samples} samples",
            )
        failed = sum(int((~s.converged.astype(bool)).sum()) for s in (dataset.train, dataset.test))
        report[name] = {
            "samples": samples,
            "test_samples": plan.n_test,
            "designs": samples,
            "failed_samples": failed,
            "design_bounds": {k: list(v) for k, v in spec["design_bounds"].items()},
            "g_test_loss": fits.design.best_test_loss,
            "g_best_epoch": fits.design.best_epoch,
            "f_test_loss": fits.condensed.best_test_loss,
            "f_best_epoch": fits.condensed.best_epoch,
            "f_hidden": list(spec["f_hidden"]),
            "g_hidden": list(spec["g_hidden"]),
            "dropout": spec["dropout"],
            "f_epochs": epochs,
            "g_epochs": design_epochs or epochs,
            "learning_rate": learning_rate,
            "batch_size": batch_size,
            "activation": activation,
            "schedule": schedule,
            "thesis": spec["thesis"],
        }
        print(name, json.dumps(report[name]))
        path.write_text(json.dumps(report, indent=1))
    report["note"] = (
        "Standardised test losses (Eq. 5.5) at the best epoch. Every sample its own design; cable"
        " 0 pulled 0-10 mm, cable 1 held at its length. Reduced sizes: see 'samples' beside"
        " the thesis'."
    )
    path.write_text(json.dumps(report, indent=1))


if __name__ == "__main__":
    typer.run(main)
