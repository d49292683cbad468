"""Calibration of a condensed model over designs to observed effector positions (thesis §5.1.6,
Eq. 5.15-5.16, Fig. 5.13).

The robot is driven to a few actuator displacements delta_a and its effector rows delta_e* are
observed; the design parameters P (e.g. the Poisson ratio) are those that minimise

    O_cal(P) = sum over delta_a of |delta_e(delta_a, P) - delta_e*(delta_a)|      (Eq. 5.15)

with delta_e from the predicted matrices by Eq. 5.16. The gradient flows through F and G.
Adam descends it, with the adaptive scheme of §5.1.2: the learning rate is cut when the
objective stops decreasing. The parameters move in the unit box of the design space (P - low)
/ (high - low), so that one learning rate suits a Young's modulus in kPa and a Poisson ratio,
and they are kept inside it, where the model was trained.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
import torch
from torch import Tensor

from pliant import robots
from pliant.condensed.dataset import CollectionPlan
from pliant.condensed.equilibrium import load_step, rest_equilibrium
from pliant.condensed.layout import Layout
from pliant.condensed.parametric import DesignMechanics, descend_in_design_box, effector_rows
from pliant.errors import LearnedModelError
from pliant.solvers import StaticSolver


@dataclass
class CalibrationResult:
    """The calibrated parameters and, per iteration, the objective, parameters and rate."""

    parameters: dict[str, float]
    objective: float
    history: list[dict] = field(default_factory=list)


def observe(
    plan: CollectionPlan, design: Mapping[str, float], commands: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The robot of `plan` with the design `design`, simulated as the physical robot stands
    for it in §5.1.6: (reached actuator displacements (n, a), effector rows (n, e)) at each
    command (n, a), its effectors measured from the plan's base-design goals, as in the data.
    """
    base = robots.build(plan.robot, **plan.robot_kwargs)
    model = robots.build(plan.robot, **{**plan.robot_kwargs, **design})
    for effector, reference in zip(model.effectors, base.effectors, strict=True):
        effector.goals = reference.goals
    layout = Layout.of(model)
    solver = StaticSolver(model, tolerance=plan.tolerance, max_iterations=plan.newton_iterations)
    state = rest_equilibrium(model, solver)
    reached, rows = [], []
    for command in np.atleast_2d(commands):
        state = load_step(model, solver, state, command, plan.max_increment)
        reached.append(state.displacement)
        positions = np.vstack([e.position(state.positions) for e in model.effectors])
        rows.append(layout.effector_rows(positions) - layout.training_goal_rows)
    return np.array(reached), np.array(rows)


def calibration_objective(
    model: DesignMechanics, delta_a: Tensor, observed: Tensor, design: Tensor
) -> Tensor:
    """Eq. 5.15: the sum over samples of the Euclidean distance between the predicted
    (Eq. 5.16) and observed effector rows, for one design (1, P)."""
    predicted = effector_rows(model, delta_a, design.expand(delta_a.shape[0], -1))
    return torch.linalg.vector_norm(predicted - observed, dim=1).sum()


def calibrate(
    model: DesignMechanics,
    delta_a: np.ndarray,
    observed: np.ndarray,
    initial: Mapping[str, float],
    *,
    fit: Sequence[str] = ("poisson_ratio",),
    learning_rate: float = 0.01,
    iterations: int = 300,
    lr_factor: float = 0.5,
    lr_patience: int = 10,
    min_learning_rate: float = 1e-5,
) -> CalibrationResult:
    """Design parameters `fit` that make the model's effector rows match `observed`.

    Args:
        delta_a: (n, a) actuator displacements of the observations.
        observed: (n, effector rows) effector rows delta_e* observed there (the layout's rows:
            weight * (p - training goal) on its axes).
        initial: a value for every design parameter; those not in `fit` are held.
        learning_rate: Adam's initial rate, in unit-box coordinates.
        lr_factor, lr_patience: the adaptive scheme, ReduceLROnPlateau on the objective.
        min_learning_rate: stop when the rate falls below it.
    """
    names = model.design_names
    missing = [k for k in names if k not in initial]
    unknown = [k for k in (*initial, *fit) if k not in names]
    if missing or unknown:
        raise LearnedModelError(
            f"the model's design parameters are {list(names)}; calibration got values for"
            f" {sorted(initial)} and fits {list(fit)}"
        )
    delta_a = torch.as_tensor(np.atleast_2d(delta_a), dtype=torch.float64)
    observed = torch.as_tensor(np.atleast_2d(observed), dtype=torch.float64)
    if len(delta_a) != len(observed):
        raise LearnedModelError(
            f"{len(delta_a)} actuator states but {len(observed)} observed effector positions"
        )
    history = descend_in_design_box(
        model,
        np.array([float(initial[k]) for k in names]),
        lambda design: calibration_objective(model, delta_a, observed, design),
        learning_rate=learning_rate,
        iterations=iterations,
        lr_factor=lr_factor,
        lr_patience=lr_patience,
        min_learning_rate=min_learning_rate,
        free=torch.tensor([k in fit for k in names]),
    )
    best = min(history, key=lambda h: h["objective"])
    return CalibrationResult({k: best[k] for k in names}, best["objective"], history)
