"""Every stepper of one model is a `Solver` (`step(state, control=None) -> state` on
`model`): the full, static, reduced, proxy and SOFA-scene solvers, each stepped through the
protocol alone; those that hold the step's factorisation also condense."""

from __future__ import annotations

import inspect

import numpy as np
from conftest import two_cable_beam

from pliant.proxy.actuation import ProxySolver
from pliant.reduction import ReducedImplicitEuler, full_basis
from pliant.solvers import CondensingSolver, ImplicitEuler, Solver, StaticSolver


def _drive(solver: Solver, state, control):
    """What a controller does, knowing only the protocol."""
    for _ in range(2):
        state = solver.step(state, control)
    return state


def test_full_static_and_reduced_solvers_are_solvers():
    model = two_cable_beam()
    pull = np.array([0.5, 0.0])
    solvers = [
        ImplicitEuler(model, 0.01),
        StaticSolver(model),
        ReducedImplicitEuler(model, full_basis(model.body), None, 0.01),
    ]
    for solver in solvers:
        assert isinstance(solver, Solver), type(solver).__name__
        assert list(inspect.signature(solver.step).parameters) == ["state", "control"]
        start = solver.rest_state() if hasattr(solver, "rest_state") else model.rest_state()
        moved = _drive(solver, start, pull)
        assert np.abs(moved.positions - model.body.rest_positions).max() > 1e-3
    assert isinstance(solvers[0], CondensingSolver) and isinstance(solvers[1], CondensingSolver)
    assert not isinstance(solvers[2], CondensingSolver)  # the reduced step gives no W


def test_a_proxy_solver_takes_its_commands_as_control():
    class Commands:  # a proxy's actuation: records the commands it is given
        def apply(self, control):
            self.applied = np.asarray(control)

    model = two_cable_beam()
    proxy = Commands()
    solver = ProxySolver(proxy, ImplicitEuler(model, 0.01))
    assert isinstance(solver, CondensingSolver)
    assert list(inspect.signature(solver.step).parameters) == ["state", "control"]
    _drive(solver, model.rest_state(), np.array([1.0, 2.0]))
    assert proxy.applied.tolist() == [1.0, 2.0]
