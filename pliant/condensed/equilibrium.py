"""Quasi-static equilibria for imposed actuator displacements (or forces: pressures of a
pneumatic robot), reached by adaptive load stepping.

The static solver's Newton iterations use the consistent tangent (exact material tangent plus
the cables' geometric stiffness) and converge quadratically, in about six iterations whatever
the size of a load step that converges at all. So the stepper tries the whole change of command
at once, and halves a step only where Newton fails.
"""

from __future__ import annotations

from typing import Literal

import numpy as np

from pliant.errors import DivergenceError, SolverError
from pliant.model import Model, State
from pliant.solvers import StaticSolver


def rest_equilibrium(model: Model, solver: StaticSolver) -> State:
    """The equilibrium with every actuator force zero (lambda_a = 0), where W0 is taken."""
    model.set_actuation(np.zeros(model.n_actuators), mode="force")
    return solver.step(model.rest_state())


def load_step(
    model: Model,
    solver: StaticSolver,
    state: State,
    target: np.ndarray,
    max_increment: float,
    *,
    min_increment: float | None = None,
    mode: Literal["displacement", "force"] = "displacement",
) -> State:
    """Equilibrium for the imposed actuator displacements `target` (with mode "force", the
    actuator forces: a pressure-controlled robot), reached from `state`.

    Static steps change no command by more than `max_increment`; where a step fails (Newton
    diverges, or the actuators' constraint QP does not converge within it), it and the steps
    after it are halved, down to `min_increment` (default max_increment / 16).
    Raises DivergenceError, naming the command where it stopped, if a smallest step fails.
    """
    if mode not in ("displacement", "force"):
        raise ValueError(f"mode must be 'displacement' or 'force', got {mode!r}")
    smallest = max_increment / 16 if min_increment is None else min_increment
    if not 0 < smallest <= max_increment:
        raise ValueError(
            f"need 0 < min_increment <= max_increment, got {smallest}, {max_increment}"
        )
    target = np.asarray(target, dtype=float)
    # the commands `state` was solved for: its displacements, or the forces of its last step
    reached = (state.displacement if mode == "displacement" else state.actuation).copy()
    increment = max_increment
    while True:
        change = target - reached
        size = float(np.max(np.abs(change), initial=0.0))
        if size == 0.0:
            return state
        fraction = min(1.0, increment / size)
        command = target if fraction == 1.0 else reached + fraction * change
        model.set_actuation(command, mode=mode)
        try:
            state = solver.step(state)
        except (DivergenceError, SolverError) as exc:
            if increment / 2 < smallest:
                raise DivergenceError(
                    f"no equilibrium reached for the commands {np.round(command, 4).tolist()}"
                    f" from {np.round(reached, 4).tolist()}, even in steps of {increment:.3g}:"
                    f" {exc}",
                    step=state.step,
                    cause="solver",
                ) from exc
            increment = min(increment, size) / 2
            continue
        reached = command
