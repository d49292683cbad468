"""Control by gradient: open-loop actuation sequences by L-BFGS-B on the rollout loss.

The controls c_0 .. c_{T-1} (T, n_a) minimise a stage loss L (:mod:`pliant.diff.losses`) of
the full FEM rollout from s_0, within the box lower <= c_n <= upper (default: the actuators'
own bounds in their modes, forces for force-mode actuators, cable lengths for displacement
ones). Each evaluation is one rollout and its adjoint (:func:`pliant.diff.rollout_gradient`):
the loss and its exact gradient with respect to every command, for the cost of a few
simulations, which scipy's L-BFGS-B turns into a quasi-Newton step within the box.

The optimiser works on c / scale (default scale: the width of each actuator's box where it
is finite, else 1), so that a cable force in mN and a cavity pressure in kPa weigh alike. At a
bound, the gradient is the one-sided derivative from inside the box (the adjoint's choice
for a force command at its bound), which is what L-BFGS-B's projected steps need.

What a box cannot hold: a bound on the change of a command from one step to the next (the
box-DDP of :mod:`pliant.trajopt` takes |c_n - c_{n-1}| <= max_change); write it as a penalty
in the loss, or reparametrise.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import minimize

from pliant.diff.losses import Loss
from pliant.diff.rollout import check_controls, check_solver, rollout_gradient
from pliant.diff.step import check_model
from pliant.errors import ConstraintError, InfeasibleProblemError
from pliant.model import Model, State
from pliant.solvers.implicit_euler import ImplicitEuler


class CountedRollouts:
    """The rollouts and adjoints an optimiser asks for, all of one model, solver, start state
    and loss (:func:`pliant.diff.rollout_gradient`), and the solver steps they took in all
    (forward passes and recomputations): what :func:`optimise_controls` and
    :func:`pliant.diff.calibration.calibrate` report."""

    def __init__(self, model, solver, state0, loss, checkpoint_every: int | None) -> None:
        self.model, self.solver, self.state0, self.loss = model, solver, state0, loss
        self.checkpoint_every = checkpoint_every
        self.forward_steps = 0

    def __call__(self, controls: np.ndarray, wrt: tuple[str, ...]):
        """:func:`pliant.diff.rollout_gradient` under `controls`, with respect to `wrt`."""
        result = rollout_gradient(
            self.model,
            self.solver,
            self.state0,
            controls,
            self.loss,
            wrt=wrt,
            checkpoint_every=self.checkpoint_every,
        )
        self.forward_steps += result.forward_steps
        return result


@dataclass
class ControlResult:
    """The optimised controls and what the optimisation cost.

    Attributes:
        controls: (T, n_a) the best controls evaluated.
        loss: their loss.
        iterations: L-BFGS-B iterations.
        evaluations: loss-and-gradient evaluations (each one full rollout and its adjoint).
        simulated_steps: solver steps taken in all (forward passes and recomputations).
        wall_time: seconds spent in the optimisation.
        history: the loss at each evaluation.
        iteration_losses: the loss at the end of each iteration, with the evaluations and
            the seconds spent by then: [(iteration, evaluations, loss, seconds), ...].
        message: the optimiser's.
        converged: whether L-BFGS-B met its tolerance (rather than its iteration cap).
    """

    controls: np.ndarray
    loss: float
    iterations: int
    evaluations: int
    simulated_steps: int
    wall_time: float
    history: list[float] = field(default_factory=list)
    iteration_losses: list[tuple[int, int, float, float]] = field(default_factory=list)
    message: str = ""
    converged: bool = False


def actuator_box(model: Model) -> tuple[np.ndarray, np.ndarray]:
    """Each actuator's command bounds in its mode: (min_force, max_force) for force-mode
    actuators, (min_displacement, max_displacement) for displacement-mode ones."""
    lower, upper = [], []
    for a in model.actuators:
        if a.mode == "displacement":
            lower.append(a.min_displacement)
            upper.append(a.max_displacement)
        else:
            lower.append(a.min_force)
            upper.append(a.max_force)
    return np.array(lower, dtype=float), np.array(upper, dtype=float)


def _command_bounds(model: Model, lower, upper) -> tuple[np.ndarray, np.ndarray]:
    """The box, checked: within the actuators' own bounds (outside them the model clips the
    command and its gradient is zero), lower <= upper, no NaN."""
    own_lo, own_hi = actuator_box(model)
    n_a = own_lo.size
    boxes = []
    for name, given, own in (("lower", lower, own_lo), ("upper", upper, own_hi)):
        if given is None:
            boxes.append(own)
            continue
        value = np.asarray(given, dtype=float)
        if value.ndim > 1 or value.size not in (1, n_a):
            raise ConstraintError(
                f"{name} bounds: a scalar or one per actuator ({n_a},), got shape {value.shape}"
            )
        value = np.broadcast_to(value, (n_a,)).copy()
        if np.any(np.isnan(value)):
            raise ConstraintError(f"{name} bounds must not be NaN")
        boxes.append(value)
    lo, hi = boxes
    if np.any(lo > hi):
        bad = np.flatnonzero(lo > hi).tolist()
        raise InfeasibleProblemError(f"lower > upper bound for actuators {bad}: no command fits")
    outside = np.flatnonzero((lo < own_lo) | (hi > own_hi)).tolist()
    if outside:
        raise ConstraintError(
            f"the bounds of actuators {outside} reach beyond the actuators' own"
            f" {own_lo[outside].tolist()}..{own_hi[outside].tolist()}: the model would clip"
            " those commands (zero gradient); narrow the box or widen the actuators' bounds"
        )
    return lo, hi


def optimise_controls(
    model: Model,
    solver: ImplicitEuler,
    state0: State,
    loss: Loss,
    initial: np.ndarray,
    *,
    lower: float | np.ndarray | None = None,
    upper: float | np.ndarray | None = None,
    scale: float | np.ndarray | None = None,
    max_iterations: int = 100,
    relative_tolerance: float = 1e-9,
    gradient_tolerance: float = 1e-9,
    memory: int = 20,
    checkpoint_every: int | None = None,
    callback=None,
) -> ControlResult:
    """Open-loop controls (T, n_a) minimising `loss` of the rollout from `state0`, by
    L-BFGS-B within the box lower <= c_n <= upper, from `initial` (projected onto the box).

    Args:
        model: the robot (see :func:`pliant.diff.rollout_gradient` for what it may hold).
        solver: its ImplicitEuler, ``tangent="fresh"``.
        state0: the initial state.
        loss: stage terms of the rollout (e.g. :class:`PointTracking` plus
            :class:`ControlPenalty`).
        initial: (T, n_a) the first guess; its length is the horizon T.
        lower, upper: the box, a scalar or one per actuator (default: the actuators' own
            bounds, :func:`actuator_box`); it must lie within the actuators' bounds.
        scale: the optimiser's unit of each command (default: the box's width where finite,
            else 1).
        max_iterations: L-BFGS-B's iteration cap.
        relative_tolerance: stop when (L_k - L_{k+1}) / max(|L_k|, |L_{k+1}|, 1) falls below it.
        gradient_tolerance: stop when the projected gradient (in scaled units) falls below it.
        memory: the number of correction pairs L-BFGS keeps.
        checkpoint_every: passed on to :func:`pliant.diff.rollout_gradient`.
        callback: ``callback(iteration, evaluations, loss, seconds)`` after each iteration.

    Raises:
        ModelError: wrong shape or non-finite `initial`, a model or solver pliant.diff does
            not differentiate.
        ConstraintError: bounds of the wrong shape, NaN, or beyond the actuators' own.
        InfeasibleProblemError: lower > upper.
    """
    check_model(model)
    check_solver(model, solver)
    initial = check_controls(model, initial)
    lo, hi = _command_bounds(model, lower, upper)
    width = hi - lo
    if scale is None:
        unit = np.where(np.isfinite(width) & (width > 0), width, 1.0)
    else:
        unit = np.broadcast_to(np.asarray(scale, dtype=float), lo.shape).copy()
        if not np.all(np.isfinite(unit) & (unit > 0)):
            raise ConstraintError(f"scale must be finite and > 0, got {unit.tolist()}")
    n_steps, n_a = initial.shape
    start = np.clip(initial, lo, hi) / unit
    box = list(zip(np.tile(lo / unit, n_steps), np.tile(hi / unit, n_steps), strict=True))
    history: list[float] = []
    iterations: list[tuple[int, int, float, float]] = []
    best = {"loss": np.inf, "controls": start * unit}
    rollouts = CountedRollouts(model, solver, state0, loss, checkpoint_every)

    def evaluate(x: np.ndarray) -> tuple[float, np.ndarray]:
        controls = np.clip(x.reshape(n_steps, n_a) * unit, lo, hi)
        result = rollouts(controls, ("controls",))
        history.append(result.value)
        if result.value < best["loss"]:
            best["loss"], best["controls"] = result.value, controls
        return result.value, (result.gradients["controls"] * unit).reshape(-1)

    def report(x: np.ndarray) -> None:
        seconds = time.perf_counter() - clock
        iterations.append((len(iterations) + 1, len(history), history[-1], seconds))
        if callback is not None:
            callback(*iterations[-1])

    clock = time.perf_counter()
    fit = minimize(
        evaluate,
        start.reshape(-1),
        jac=True,
        method="L-BFGS-B",
        bounds=box,
        callback=report,
        options={
            "maxiter": max_iterations,
            "ftol": relative_tolerance,
            "gtol": gradient_tolerance,
            "maxcor": memory,
        },
    )
    return ControlResult(
        controls=best["controls"],
        loss=float(best["loss"]),
        iterations=int(fit.nit),
        evaluations=len(history),
        simulated_steps=rollouts.forward_steps,
        wall_time=time.perf_counter() - clock,
        history=history,
        iteration_losses=iterations,
        message=str(fit.message),
        converged=bool(fit.success) and int(fit.nit) < max_iterations,
    )
