"""Quasi-static equilibria for imposed actuator displacements, reached by load stepping."""

from __future__ import annotations

import math

import numpy as np

from pliant.model import Model, State
from pliant.solvers import StaticSolver


def rest_equilibrium(model: Model, solver: StaticSolver) -> State:
    """The equilibrium with every actuator force zero (lambda_a = 0), where W0 is taken."""
    model.set_actuation(np.zeros(model.n_actuators), mode="force")
    return solver.step(model.rest_state())


def load_step(
    model: Model, solver: StaticSolver, state: State, target: np.ndarray, max_increment: float
) -> State:
    """Equilibrium for the imposed actuator displacements `target`, reached from `state` in
    static steps that change no command by more than `max_increment` (Newton converges from a
    nearby equilibrium where a jump would not). Raises DivergenceError if a step fails."""
    start = state.displacement
    n = max(1, math.ceil(float(np.max(np.abs(target - start), initial=0.0)) / max_increment))
    for k in range(1, n + 1):
        model.set_actuation(start + (target - start) * k / n, mode="displacement")
        state = solver.step(state)
    return state
