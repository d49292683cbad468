"""What every solver shares: the step report and the divergence checks."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from pliant.constraints.condensed import CondensedProblem
from pliant.constraints.friction import ContactReport
from pliant.errors import DivergenceError
from pliant.fem.body import Linearisation


@dataclass
class StepReport:
    """What happened in the last step (for logging, controllers and tests)."""

    problem: CondensedProblem | None = None
    actuation: np.ndarray = field(default_factory=lambda: np.zeros(0))
    linear_iterations: int = 0
    factorisations: int = 0
    newton_iterations: int = 0
    contact: ContactReport | None = None  # None: no contact rows at this step


def check_linearisation(lin: Linearisation, step: int, dt: float | None) -> None:
    """Raise DivergenceError if elements are inverted or forces are not finite."""
    hint = (
        f"reduce the time step (now {dt}) or the actuation rate"
        if dt is not None
        else "reduce the load or actuation per static step (load stepping)"
    )
    if (
        lin.dets.size
        and lin.dets.min() > 0.0
        and math.isfinite(float(lin.forces.sum()))
        and math.isfinite(lin.energy)
    ):
        return  # the usual case, in two passes over the arrays
    if lin.n_inverted:
        first = int(np.flatnonzero(~(lin.dets > 0))[0])
        raise DivergenceError(
            f"step {step}: {lin.n_inverted} element(s) inverted (first: element {first},"
            f" det F = {lin.dets[first]:.3g}); {hint}",
            step=step,
            cause="inverted",
        )
    if not (np.all(np.isfinite(lin.forces)) and np.isfinite(lin.energy)):
        raise DivergenceError(
            f"step {step}: non-finite internal forces; {hint}", step=step, cause="non-finite"
        )


def check_motion(
    positions: np.ndarray,
    velocities: np.ndarray,
    displacement: np.ndarray,
    size: float,
    step: int,
    dt: float | None,
) -> None:
    """Raise DivergenceError for non-finite states or a jump larger than the body itself."""
    hint = (
        f"reduce the time step (now {dt}) or the actuation rate"
        if dt is not None
        else "reduce the load or actuation per static step (load stepping)"
    )
    # One pass each; a sum that overflows on finite values is told apart by the full check.
    finite = math.isfinite(float(positions.sum()) + float(velocities.sum())) or (
        np.all(np.isfinite(positions)) and np.all(np.isfinite(velocities))
    )
    if not finite:
        raise DivergenceError(
            f"step {step}: the state became non-finite; {hint}", step=step, cause="non-finite"
        )
    jump = float(np.max(np.abs(displacement))) if displacement.size else 0.0
    if jump > size:
        raise DivergenceError(
            f"step {step}: a node moved {jump:.3g} in one step, more than the body's size"
            f" ({size:.3g}): energy blow-up; {hint}",
            step=step,
            cause="energy",
        )
