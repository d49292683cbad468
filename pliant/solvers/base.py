"""What every solver shares: the step report and the divergence checks."""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, field

import numpy as np

from pliant.constraints.condensed import CondensedProblem
from pliant.constraints.control import as_control
from pliant.constraints.friction import ContactReport
from pliant.errors import DivergenceError, SolverError
from pliant.fem.body import Linearisation
from pliant.fem.kernels import motion_check


@dataclass
class StepReport:
    """What happened in the last step (for logging, controllers and tests)."""

    problem: CondensedProblem | None = None
    actuation: np.ndarray = field(default_factory=lambda: np.zeros(0))
    linear_iterations: int = 0
    factorisations: int = 0
    newton_iterations: int = 0
    contact: ContactReport | None = None  # None: no contact rows at this step
    # The static solver held the actuators where a feedback control's last iterate put them,
    # the control and the equilibrium cycling instead of converging together (a best effort).
    held: bool = False


def number_option(
    value,
    name: str,
    *,
    above: float | None = None,
    at_least: float | None = None,
    integer: bool = False,
    error: type[Exception] = SolverError,
) -> float | int:
    """`value` as a float (an int with `integer`), checked where it enters: a real number
    (any NumPy scalar, not a bool or a string), finite, > `above` or >= `at_least`; `error`
    names the option otherwise, so that a bad setting is not reported later as a divergence."""
    kind = numbers.Integral if integer else numbers.Real
    if isinstance(value, bool) or not isinstance(value, kind):
        what = "an integer" if integer else "a real number"
        raise error(f"{name} must be {what}, got {value!r}")
    if not math.isfinite(value):
        raise error(f"{name} must be finite, got {value!r}")
    if above is not None and not value > above:
        raise error(f"{name} must be > {above:g}, got {value!r}")
    if at_least is not None and not value >= at_least:
        raise error(f"{name} must be >= {at_least:g}, got {value!r}")
    return int(value) if integer else float(value)


def _hint(dt: float | None) -> str:
    """What to change when a step diverges (`dt` None: a static step)."""
    if dt is not None:
        return f"reduce the time step (now {dt}) or the actuation rate"
    return "reduce the load or actuation per static step (load stepping)"


def check_linearisation(lin: Linearisation, step: int, dt: float | None) -> None:
    """Raise DivergenceError if elements are inverted or forces are not finite."""
    if (
        lin.dets.size
        and lin.dets.min() > 0.0
        and math.isfinite(float(lin.forces.sum()))
        and math.isfinite(lin.energy)
    ):
        return  # the usual case, in two passes over the arrays
    if lin.n_inverted and not lin.tolerates_inversion:
        first = int(np.flatnonzero(~(lin.dets > 0))[0])
        raise DivergenceError(
            f"step {step}: {lin.n_inverted} element(s) inverted (first: element {first},"
            f" det F = {lin.dets[first]:.3g}); {_hint(dt)}",
            step=step,
            cause="inverted",
        )
    if not (np.all(np.isfinite(lin.forces)) and np.isfinite(lin.energy)):
        raise DivergenceError(
            f"step {step}: non-finite internal forces; {_hint(dt)}", step=step, cause="non-finite"
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
    if positions.ndim == velocities.ndim == displacement.ndim == 2:
        finite, jump = motion_check(positions, velocities, displacement)  # one compiled pass
    else:
        # One pass each; a sum that overflows on finite values is told apart by the full check.
        finite = math.isfinite(float(positions.sum()) + float(velocities.sum())) or (
            np.all(np.isfinite(positions)) and np.all(np.isfinite(velocities))
        )
        jump = float(np.max(np.abs(displacement))) if finite and displacement.size else 0.0
    if not finite:
        raise DivergenceError(
            f"step {step}: the state became non-finite; {_hint(dt)}", step=step, cause="non-finite"
        )
    if jump > size:
        raise DivergenceError(
            f"step {step}: a node moved {jump:.3g} in one step, more than the body's size"
            f" ({size:.3g}): energy blow-up; {_hint(dt)}",
            step=step,
            cause="energy",
        )


def begin_control(model, state, control):
    """The step's control object from `control` (None, commands or a control): its commands
    written to the model, then, for a feedback control, its goals set from the state the
    step starts from (its optional ``begin``)."""
    ctrl = as_control(control)
    ctrl.prepare(model)
    begin = getattr(ctrl, "begin", None)
    if begin is not None:
        begin(model, state)
    return ctrl
