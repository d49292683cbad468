"""The condensed model over designs, F(delta_a, delta_c, G(P)) (thesis Eq. 5.7-5.8, Fig. 5.3).

G maps design parameters P (geometry, material) to the rest values (W0, delta0_free); F maps
them and the actuator state to (W, delta_free). Their composition is a differentiable map from
the design to the robot's mechanics, which calibration (Eq. 5.15-5.16) and design optimisation
(Eq. 5.17-5.20) descend. Computations run in float64: the objectives difference predictions.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

import numpy as np
import torch
from torch import Tensor

from pliant.condensed.dataset import CollectionPlan, Dataset
from pliant.condensed.layout import Layout
from pliant.condensed.learned import (
    check_finite,
    load_model_file,
    model_record,
    write_model_file,
)
from pliant.condensed.mechanics import effector_displacement, symmetric
from pliant.condensed.networks import ComposedNetwork, StandardisedMLP
from pliant.condensed.sampling import Box
from pliant.condensed.train import FitResult, TrainConfig, train_condensed, train_design
from pliant.errors import DatasetError, LearnedModelError

FORMAT = "pliant-parametric-condensed"
FORMAT_VERSION = 1


class DesignMechanics(Protocol):
    """What calibration and design read of a condensed model over designs: its layout, the
    names and box of its design parameters, and W, delta_free at (delta_a, P), differentiably.
    :class:`ParametricCondensedModel` is one; an analytic model can stand for it in tests."""

    layout: Layout
    design_names: tuple[str, ...]
    design_box: Box

    def matrices(self, delta_a: Tensor, design: Tensor) -> tuple[Tensor, Tensor]:
        """(W (n, rows, rows), delta_free (n, rows)) for delta_a (n, a) and design (n, P)."""
        ...

    def rest(self, design: Tensor) -> tuple[Tensor, Tensor]:
        """(W0, delta0_free) of each design (n, P), at lambda = 0."""
        ...


def effector_rows(model: DesignMechanics, delta_a: Tensor, design: Tensor) -> Tensor:
    """Eq. 5.16 with the model's matrices: the effector rows reached for delta_a (n, a)."""
    w, free = model.matrices(delta_a, design)
    slices = model.layout.slices
    return effector_displacement(w, free, delta_a, slices["actuator"], slices["effector"])


@dataclass
class ParametricFit:
    """The two trainings behind a parametric model."""

    condensed: FitResult
    design: FitResult


class ParametricCondensedModel:
    """F and G with the layout and design space they learned (float64, evaluation mode).

    Args:
        condensed: F, raw (delta_a, delta_c, W0 triangle, delta0_free) -> (W triangle,
            delta_free).
        design: G, raw P -> (W0 triangle, delta0_free).
        plan: how the dataset was collected; its design bounds are the design box.
        input_box: region of actuator (and contact) displacements in the training data.
        training: what the trainings reported, kept with the model.
    """

    def __init__(
        self,
        condensed: StandardisedMLP,
        design: StandardisedMLP,
        layout: Layout,
        plan: CollectionPlan,
        input_box: Box,
        training: dict | None = None,
    ) -> None:
        if not plan.design_names:
            raise LearnedModelError("a parametric model needs a dataset over design parameters")
        n_rest = layout.n_triangle + layout.n_rows
        expected = {
            "F": (condensed, input_box.dim + n_rest, n_rest),
            "G": (design, len(plan.design_names), n_rest),
        }
        for name, (network, n_in, n_out) in expected.items():
            if (network.n_inputs, network.n_outputs) != (n_in, n_out):
                raise LearnedModelError(
                    f"{name} maps {network.n_inputs} -> {network.n_outputs} values; the layout"
                    f" and design need {n_in} -> {n_out}"
                )
        check_finite(condensed, "F")
        check_finite(design, "G")
        self.network = ComposedNetwork(condensed, design).to(torch.float64).eval()
        self.layout = layout
        self.plan = plan
        self.design_names = plan.design_names
        self.design_box = plan.design_box
        self.input_box = input_box
        self.training = dict(training or {})

    def _split(self, y: Tensor) -> tuple[Tensor, Tensor]:
        n = self.layout.n_triangle
        return symmetric(y[..., :n], self.layout.n_rows), y[..., n:]

    def rest(self, design: Tensor) -> tuple[Tensor, Tensor]:
        return self._split(self.network.design.predict(design))

    def matrices(self, delta_a: Tensor, design: Tensor) -> tuple[Tensor, Tensor]:
        n_contact = self.input_box.dim - delta_a.shape[-1]
        displacements = torch.cat([delta_a, delta_a.new_zeros(delta_a.shape[0], n_contact)], 1)
        return self._split(self.network(displacements, design))

    def design_tensor(self, **values: float) -> Tensor:
        """P as a (1, P) tensor from keyword values; the plan's base design fills the rest."""
        unknown = set(values) - set(self.design_names)
        if unknown:
            raise LearnedModelError(
                f"unknown design parameters {sorted(unknown)}; this model has"
                f" {list(self.design_names)}"
            )
        centre = 0.5 * (self.design_box.low + self.design_box.high)
        base = [
            values.get(k, self.plan.robot_kwargs.get(k, centre[i]))
            for i, k in enumerate(self.design_names)
        ]
        return torch.tensor([base], dtype=torch.float64)

    def save(self, path: str | os.PathLike) -> Path:
        """Write the model atomically (LearnedModelError, nothing left behind, on failure)."""
        networks = {
            name: {"config": net.config(), "state": _float32_where_exact(net.state_dict())}
            for name, net in (
                ("condensed", self.network.condensed),
                ("design", self.network.design),
            )
        }
        record = model_record(FORMAT, FORMAT_VERSION, self, {"networks": networks})
        return write_model_file(path, record)

    @classmethod
    def load(cls, path: str | os.PathLike) -> ParametricCondensedModel:
        return load_model_file(path, FORMAT, FORMAT_VERSION, "parametric condensed model", cls._of)

    @classmethod
    def _of(cls, data: dict) -> ParametricCondensedModel:
        networks = {}
        for name, saved in data["networks"].items():
            networks[name] = StandardisedMLP.from_config(saved["config"])
            networks[name].load_state_dict(saved["state"])
        return cls(
            networks["condensed"],
            networks["design"],
            Layout.from_dict(data["layout"]),
            CollectionPlan.from_dict(data["plan"]),
            Box(*data["input_box"]),
            data["training"],
        )


def _float32_where_exact(state: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
    """The float64 tensors whose values are float32 numbers stored as float32: F and G train
    in float32 and are cast up to evaluate, so a model file holds the same numbers in half the
    bytes (loading casts them up again); any other tensor as it is."""
    return {
        key: value.float()
        if value.dtype == torch.float64 and torch.equal(value.float().double(), value)
        else value
        for key, value in state.items()
    }


def train_parametric(
    dataset: Dataset,
    condensed: TrainConfig | None = None,
    design: TrainConfig | None = None,
) -> tuple[ParametricCondensedModel, ParametricFit]:
    """Train G (Eq. 5.7) and F (Eq. 5.2) on a dataset over designs, apart, as the thesis does
    (F learns from the FEM's W0 and delta0_free; it is used on G's)."""
    if not dataset.plan.design_names:
        raise DatasetError("the dataset has no design parameters: collect it with design_bounds")
    learned, fit_f = train_condensed(dataset, condensed)
    fit_g = train_design(dataset, design)
    training = {
        "condensed": {"best_epoch": fit_f.best_epoch, "test_loss": fit_f.best_test_loss},
        "design": {"best_epoch": fit_g.best_epoch, "test_loss": fit_g.best_test_loss},
    }
    model = ParametricCondensedModel(
        learned.network, fit_g.network, dataset.layout, dataset.plan, learned.input_box, training
    )
    return model, ParametricFit(fit_f, fit_g)


def descend_in_design_box(
    model: DesignMechanics,
    start: np.ndarray,
    objective: Callable[[torch.Tensor], torch.Tensor],
    *,
    learning_rate: float,
    iterations: int,
    lr_factor: float,
    lr_patience: int,
    min_learning_rate: float = 0.0,
    free: torch.Tensor | None = None,
) -> list[dict]:
    """Adam on `objective(design)` (design: (1, d)) in the unit box of the model's design space
    from `start`, projected back into the box after each step, the rate cut on plateaus
    (ReduceLROnPlateau, §5.1.2); the parameters where `free` is False are held. Stops after
    `iterations` steps or when the rate falls below `min_learning_rate`. Returns the history:
    one record per iterate (iteration, objective, learning rate and the design's values)."""
    box = model.design_box
    low = torch.as_tensor(box.low, dtype=torch.float64)
    span = torch.as_tensor(box.high - box.low, dtype=torch.float64)
    span = torch.where(span > 0, span, torch.ones_like(span))
    start_t = torch.as_tensor(np.asarray(start, dtype=float), dtype=torch.float64)
    unit = ((start_t - low) / span).clamp(0.0, 1.0).requires_grad_(True)
    optimiser = torch.optim.Adam([unit], lr=learning_rate)
    scheduler = torch.optim.lr_scheduler.ReduceLROnPlateau(
        optimiser, factor=lr_factor, patience=lr_patience
    )
    history: list[dict] = []
    for iteration in range(iterations + 1):
        design = (low + span * unit).unsqueeze(0)
        value = objective(design)
        lr = optimiser.param_groups[0]["lr"]
        history.append(
            {
                "iteration": iteration,
                "objective": float(value.detach()),
                "learning_rate": lr,
                **{
                    k: float(v) for k, v in zip(model.design_names, design[0].detach(), strict=True)
                },
            }
        )
        if iteration == iterations or lr < min_learning_rate:
            break
        optimiser.zero_grad()
        value.backward()
        if free is not None:
            unit.grad[~free] = 0.0
        optimiser.step()
        scheduler.step(float(value.detach()))
        with torch.no_grad():
            unit.clamp_(0.0, 1.0)
    return history
