"""Calibration by gradient: material and damping parameters fitted to observed trajectories.

The loss is the mean squared distance between simulated and observed points over the
observed stages, L(p) = 1/(2 N) sum_n sum_j |x_j(t_n; p) - y_j(t_n)|^2 (mm^2), minimised by
scipy's L-BFGS-B within bounds. Each evaluation is one rollout and its adjoint
(:func:`pliant.diff.rollout_gradient`): the loss and every parameter's derivative for about
the cost of two or three simulations, where a derivative-free search (the Bayesian
optimisation of the proxies' calibration) spends one simulation per trial and many trials per
parameter. The optimiser works on p / p_start, so that E (kPa) and nu (1) weigh alike.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import minimize

from pliant.constraints.base import EmbeddedPoints
from pliant.diff.control import CountedRollouts
from pliant.diff.losses import PointTracking
from pliant.diff.parameters import set_parameters
from pliant.diff.rollout import check_controls, rollout
from pliant.errors import ModelError
from pliant.model import Model, State
from pliant.solvers.implicit_euler import ImplicitEuler

#: Parameters a calibration fits.
CALIBRATED = ("young_modulus", "poisson_ratio", "rayleigh_mass", "rayleigh_stiffness")


@dataclass
class CalibrationResult:
    """The fitted parameters and what the fit cost.

    Attributes:
        parameters: name -> fitted value.
        loss: the final loss (mm^2).
        evaluations: loss-and-gradient evaluations (each one rollout and its adjoint).
        simulated_steps: solver steps taken in all (forward passes and recomputations).
        iterations: L-BFGS-B iterations.
        history: (loss, parameters) at each evaluation.
        message: the optimiser's.
    """

    parameters: dict[str, float]
    loss: float
    evaluations: int
    simulated_steps: int
    iterations: int
    history: list[tuple[float, dict[str, float]]] = field(default_factory=list)
    message: str = ""


def trajectory_loss(
    points: EmbeddedPoints, observed: np.ndarray, stages: list[int] | str = "all"
) -> PointTracking:
    """The calibration loss as a stage loss: 1/(2 N) sum |x - y|^2 over the stages observed
    (observed: (T + 1, k, 3))."""
    observed = np.asarray(observed, dtype=float)
    n_steps = observed.shape[0] - 1
    count = (n_steps + 1 if stages == "all" else 1 if stages == "final" else len(stages)) * len(
        points
    )
    return PointTracking(points, observed, n_steps=n_steps, weight=1.0 / count, stages=stages)


def calibrate(
    model: Model,
    solver: ImplicitEuler,
    state0: State,
    controls: np.ndarray,
    points: EmbeddedPoints,
    observed: np.ndarray,
    start: dict[str, float],
    bounds: dict[str, tuple[float, float]],
    *,
    stages: list[int] | str = "all",
    max_iterations: int = 100,
    checkpoint_every: int | None = None,
) -> CalibrationResult:
    """Fit the parameters of `start` (names in :data:`CALIBRATED`) so that `points` follow
    `observed` (T + 1, k, 3) under `controls` (T, n_a) from `state0`; the model is left with
    the fitted values.

    Raises:
        ModelError: unknown parameter, a start outside its bounds, wrong shapes.
    """
    names = tuple(start)
    unknown = [n for n in names if n not in CALIBRATED]
    if unknown or not names:
        raise ModelError(f"calibrate fits some of {CALIBRATED}, got {list(start)}")
    missing = [n for n in names if n not in bounds]
    if missing:
        raise ModelError(f"give bounds for {missing}")
    controls = check_controls(model, controls)
    observed = np.asarray(observed, dtype=float)
    if observed.shape != (controls.shape[0] + 1, len(points), 3):
        raise ModelError(
            f"observed must be ({controls.shape[0] + 1}, {len(points)}, 3), got {observed.shape}"
        )
    scale = np.array([float(start[n]) for n in names])
    if np.any(scale <= 0):
        raise ModelError("calibrate scales by the start values: give them > 0")
    box = [(bounds[n][0] / s, bounds[n][1] / s) for n, s in zip(names, scale, strict=True)]
    if any(not lo <= 1.0 <= hi for lo, hi in box):
        raise ModelError("every start value must lie within its bounds")
    loss = trajectory_loss(points, observed, stages)
    history: list[tuple[float, dict[str, float]]] = []
    rollouts = CountedRollouts(model, solver, state0, loss, checkpoint_every)

    def evaluate(x: np.ndarray) -> tuple[float, np.ndarray]:
        values = dict(zip(names, (x * scale).tolist(), strict=True))
        set_parameters(model, **values)
        result = rollouts(controls, names)
        history.append((result.value, values))
        grad = np.array([result.gradients[n] for n in names]) * scale
        return result.value, grad

    fit = minimize(
        evaluate,
        np.ones(len(names)),
        jac=True,
        method="L-BFGS-B",
        bounds=box,
        options={"maxiter": max_iterations, "ftol": 1e-16, "gtol": 1e-14, "maxcor": 20},
    )
    best = min(range(len(history)), key=lambda i: history[i][0])
    set_parameters(model, **history[best][1])
    return CalibrationResult(
        dict(history[best][1]),
        float(history[best][0]),
        len(history),
        rollouts.forward_steps,
        int(fit.nit),
        history,
        str(fit.message),
    )


def observe(
    model: Model,
    solver: ImplicitEuler,
    state0: State,
    controls: np.ndarray,
    points: EmbeddedPoints,
) -> np.ndarray:
    """The points' positions (T + 1, k, 3) along the rollout: synthetic observations."""
    return np.stack(
        [points.positions(s.positions) for s in rollout(model, solver, state0, controls)]
    )


def relative_errors(found: dict[str, float], truth: dict[str, float]) -> dict[str, float]:
    return {n: abs(found[n] - truth[n]) / abs(truth[n]) for n in found if not math.isnan(found[n])}
