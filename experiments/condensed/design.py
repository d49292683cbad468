"""Fig. 5.15-5.17 analogue: design of the parametric Soft Finger through its condensed model.

A dataset over Length 38-42, Height 20-22 and Joint Height 5-8 mm (thesis Table 5.6), cable 0
pulled 0-10 mm and cable 1 held at its length (the thesis' parametric finger has one cable),
trains G and F. Then, on the learned model alone: the dexterity and strength objectives
(Eq. 5.17, 5.19) on a 10 x 6 x 10 grid (600 designs), gradient refinement of each and of their
normalised sum (Eq. 5.20, gamma = 0.5, 0.5) from the grid's best, landscapes, Pareto front.
Finally the FEM checks the learned objectives at the grid's extreme and refined designs (the
same formulas on the FEM's own W and delta_free; ``fem_check_gap``, the worst relative gap of
the learned objectives to the FEM's over those designs):

    OPENBLAS_NUM_THREADS=1 python experiments/condensed/design.py --samples 640 --epochs 1500

The same study on any parametric model: `pliant condensed design MODEL --out FOLDER`.

The trained model is kept (``design/model.pt``, F 3 x 450 and G 2 x 64, issue #61):
``--evaluate MODEL`` re-makes every figure (the study and the FEM checks depend on the model
alone) without collecting or training:

    python experiments/condensed/design.py \
        --evaluate experiments/results/condensed/design/model.pt --out out/design_evaluate
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import numpy as np
import torch
import typer

from pliant import robots
from pliant.condensed.collect import load_or_collect
from pliant.condensed.dataset import CollectionPlan
from pliant.condensed.design import FingerObjectives, design_study
from pliant.condensed.equilibrium import load_step, rest_equilibrium
from pliant.condensed.layout import Layout
from pliant.condensed.mechanics import symmetric
from pliant.condensed.parametric import ParametricCondensedModel, train_parametric
from pliant.condensed.plots import plot_design_study
from pliant.condensed.train import TrainConfig
from pliant.files import write_json
from pliant.solvers import StaticSolver

GEOMETRY = {"length": (38.0, 42.0), "height": (20.0, 22.0), "joint_height": (5.0, 8.0)}


class FemMechanics:
    """The FEM's exact W and delta_free at the pull and at rest, for the designs asked (solved
    once per design), behind the interface the objectives read of a learned model."""

    def __init__(self, model: ParametricCondensedModel, command: np.ndarray) -> None:
        self.layout = model.layout
        self.design_names = model.design_names
        self.design_box = model.design_box
        self.plan = model.plan
        self.command = command
        self._goals = robots.build(model.plan.robot, **model.plan.robot_kwargs).effectors
        self._solved: dict[tuple[float, ...], tuple[np.ndarray, ...]] = {}

    def _solve(self, design: np.ndarray) -> tuple[np.ndarray, ...]:
        key = tuple(design.tolist())
        if key not in self._solved:
            self._solved[key] = self._solve_fem(design)
        return self._solved[key]

    def _solve_fem(self, design: np.ndarray) -> tuple[np.ndarray, ...]:
        kwargs = dict(zip(self.design_names, design.tolist(), strict=True))
        fem = robots.build(self.plan.robot, **{**self.plan.robot_kwargs, **kwargs})
        for effector, reference in zip(fem.effectors, self._goals, strict=True):
            effector.goals = reference.goals
        layout = Layout.of(fem)
        solver = StaticSolver(fem, tolerance=self.plan.tolerance, max_iterations=60)
        rest = rest_equilibrium(fem, solver)
        pulled = load_step(fem, solver, rest, self.command, self.plan.max_increment)
        return (*layout.pack(solver.condense(pulled)), *layout.pack(solver.condense(rest)))

    def _stack(self, design: torch.Tensor, first: int) -> tuple[torch.Tensor, torch.Tensor]:
        solved = [self._solve(d) for d in design.detach().numpy()]
        w = torch.as_tensor(np.array([s[first] for s in solved]))
        free = torch.as_tensor(np.array([s[first + 1] for s in solved]))
        return symmetric(w, self.layout.n_rows), free

    def matrices(self, delta_a: torch.Tensor, design: torch.Tensor):
        return self._stack(design, 0)

    def rest(self, design: torch.Tensor):
        return self._stack(design, 2)


def main(
    samples: Annotated[int, typer.Option()] = 640,
    samples_per_design: Annotated[int, typer.Option()] = 8,
    epochs: Annotated[int, typer.Option()] = 1500,
    learning_rate: Annotated[float, typer.Option(help="training rate")] = 1e-3,
    iterations: Annotated[int, typer.Option(help="gradient steps per refinement")] = 200,
    workers: Annotated[int, typer.Option()] = 1,
    work: Annotated[Path, typer.Option(help="datasets, checkpoints, models")] = Path(
        "out/condensed"
    ),
    out: Annotated[Path, typer.Option(help="results")] = Path("experiments/results/condensed"),
    kept: Annotated[
        Path | None,
        typer.Option("--evaluate", help="the study of this kept model; collect and train nothing"),
    ] = None,
) -> None:
    if kept is not None:
        design_figures(ParametricCondensedModel.load(kept), iterations, out / "design")
        return
    plan = CollectionPlan(
        "finger",
        ((0.0, 10.0), (0.0, 0.0)),
        samples,
        design_bounds=GEOMETRY,
        samples_per_design=samples_per_design,
    )
    path = work / f"finger_design_{samples}.h5"
    dataset = load_or_collect(plan, path, workers=workers)

    def config(name: str, hidden: tuple[int, ...]) -> TrainConfig:
        widths = "-".join(str(h) for h in hidden)
        return TrainConfig(
            epochs=epochs,
            learning_rate=learning_rate,
            batch_size=32,
            hidden=hidden,
            checkpoint=path.with_suffix(f".{name}-{widths}.ckpt"),
            progress=False,
        )

    # G maps three numbers to 20 from 80 designs, each meshed anew (its W0 carries the
    # remeshing's noise): a small network overfits it less than 3 x 450
    model, _ = train_parametric(dataset, config("f", (450, 450, 450)), config("g", (64, 64)))
    model.save(out / "design" / "model.pt")
    design_figures(model, iterations, out / "design")


def design_figures(model: ParametricCondensedModel, iterations: int, folder: Path) -> None:
    """The design study on `model` and its FEM checks: figures and design.json in `folder`."""
    objectives = FingerObjectives()
    study = design_study(model, objectives, iterations=iterations)
    plot_design_study(study, folder)
    summary = study.summary()

    # the learned objectives against the FEM's at telling designs
    fem = FemMechanics(model, np.array(objectives.command))
    checked = {
        "most_dexterous_grid": study.grid[int(np.argmin(study.dexterity))],
        "strongest_grid": study.grid[int(np.argmin(study.strength))],
        **{f"refined_{k}": r.design for k, r in study.refined.items()},
    }
    check = {}
    for name, design in checked.items():
        p = torch.as_tensor(design[None], dtype=torch.float64)
        with torch.no_grad():
            check[name] = {
                "design": dict(zip(study.names, design.tolist(), strict=True)),
                "angle_rad": {
                    "learned": float(objectives.bending_angle(model, p)[0]),
                    "fem": float(objectives.bending_angle(fem, p)[0]),
                },
                "tip_force_mN": {
                    "learned": float(objectives.tip_force(model, p)[0]),
                    "fem": float(objectives.tip_force(fem, p)[0]),
                },
            }
        print(name, json.dumps(check[name]))
    summary["fem_check"] = check
    # the learned objectives' worst relative gap to the FEM's over the designs checked
    summary["fem_check_gap"] = {
        f"{key}_max_relative": max(
            abs(c[key]["learned"] - c[key]["fem"]) / abs(c[key]["fem"]) for c in check.values()
        )
        for key in ("angle_rad", "tip_force_mN")
    }
    summary["training"] = model.training
    summary["samples"] = model.plan.n_train
    summary["samples_per_design"] = model.plan.samples_per_design
    summary["note"] = (
        "Cable 0 pulled 10 mm, cable 1 held at its length. alpha: angle between the tip's"
        " chords from the root at rest and pulled; beta: |lambda_c^z| on the tip held at its"
        " rest position (Eq. 5.18, W and delta_free at the free pull, as in the thesis)."
    )
    write_json(folder / "design.json", summary)


if __name__ == "__main__":
    typer.run(main)
