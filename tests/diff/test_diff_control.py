"""Control by gradient (pliant.diff.control): L-BFGS-B on a rollout loss finds a known optimum."""

from __future__ import annotations

import numpy as np
import pytest
from test_diff import DT, beam

from pliant.constraints.base import EmbeddedPoints
from pliant.diff import (
    ControlPenalty,
    Losses,
    PointTracking,
    optimise_controls,
    rollout,
    rollout_gradient,
)
from pliant.errors import ConstraintError, InfeasibleProblemError, ModelError
from pliant.solvers.implicit_euler import ImplicitEuler

T = 5


def _problem():
    """The beam with both cables in force mode; the tip nodes' trajectory under a known
    cable-force sequence is the target, so that sequence is an optimum of loss 0."""
    model = beam(modes=("force", "force"))
    solver = ImplicitEuler(model, DT, tangent="fresh")
    x = model.body.rest_positions
    tip = EmbeddedPoints.at_nodes(np.flatnonzero(np.isclose(x[:, 0], 60.0)))
    truth = np.column_stack([np.linspace(20.0, 120.0, T), np.linspace(60.0, 10.0, T)])
    states = rollout(model, solver, model.rest_state(), truth)
    targets = np.stack([tip.positions(s.positions) for s in states])
    return model, solver, tip, truth, PointTracking(tip, targets, n_steps=T)


def test_lbfgs_recovers_the_cable_sequence_that_made_the_target():
    model, solver, _, truth, loss = _problem()
    result = optimise_controls(model, solver, model.rest_state(), loss, np.zeros((T, 2)))
    # The optimum is the generating sequence, loss 0: the fit reaches 1e-8 of the start's
    # loss, and the forces (tens of mN) to well under 1 %.
    assert result.loss <= 1e-8 * result.history[0]
    assert np.abs(result.controls - truth).max() < 0.01 * np.abs(truth).max()
    assert result.controls.min() >= 0.0 and result.controls.max() <= 1e3
    assert result.evaluations == len(result.history) and result.iterations >= 1


def test_an_upper_bound_below_the_optimum_is_met_with_the_constrained_optimum():
    """With cable 0 capped below the generating forces, the solution sits on the cap where
    the unconstrained optimum lies beyond it, and the box holds."""
    model, solver, _, truth, loss = _problem()
    cap = 50.0
    result = optimise_controls(
        model,
        solver,
        model.rest_state(),
        Losses(loss, ControlPenalty(1e-8)),
        np.zeros((T, 2)),
        upper=[cap, 1e3],
        max_iterations=30,
    )
    assert result.controls[:, 0].max() <= cap
    assert np.isclose(result.controls[-1, 0], cap)  # truth ends at 120 > cap: held at the cap
    assert result.loss < result.history[0]


def test_bad_bounds_and_shapes_raise():
    model, solver, _, _, loss = _problem()
    state = model.rest_state()
    start = np.zeros((T, 2))
    with pytest.raises(ModelError, match="controls must be"):
        optimise_controls(model, solver, state, loss, np.zeros((T, 3)))
    with pytest.raises(ModelError, match="finite"):
        optimise_controls(model, solver, state, loss, np.full((T, 2), np.nan))
    with pytest.raises(InfeasibleProblemError, match="lower > upper"):
        optimise_controls(model, solver, state, loss, start, lower=[10.0, 0.0], upper=[5.0, 1.0])
    with pytest.raises(ConstraintError, match="one per actuator"):
        optimise_controls(model, solver, state, loss, start, upper=[1.0, 2.0, 3.0])
    with pytest.raises(ConstraintError, match="NaN"):
        optimise_controls(model, solver, state, loss, start, lower=np.nan)
    with pytest.raises(ConstraintError, match="beyond the actuators' own"):
        optimise_controls(model, solver, state, loss, start, lower=-1.0)
    with pytest.raises(ConstraintError, match="scale"):
        optimise_controls(model, solver, state, loss, start, scale=0.0)
    with pytest.raises(ModelError, match="fresh"):
        lagged = ImplicitEuler(model, DT, tangent="lagged")
        optimise_controls(model, lagged, state, loss, start)


def test_force_command_at_its_bound_gets_the_inside_derivative():
    """A force command at min_force = 0 enters with the derivative from inside the box (what
    L-BFGS-B's projected steps need), checked with a second-order one-sided difference
    (-3 L(c) + 4 L(c + e) - L(c + 2 e)) / (2 e); the loss also tracks the tip's velocity."""
    model, solver, tip, _, _ = _problem()
    controls = np.column_stack([np.zeros(T), np.linspace(30.0, 50.0, T)])
    goal = tip.positions(model.body.rest_positions) + [0.0, 0.0, 2.0]
    loss = Losses(
        PointTracking(tip, goal, n_steps=T),
        PointTracking(tip, np.zeros((len(tip), 3)), n_steps=T, weight=0.1, quantity="velocities"),
    )
    state = model.rest_state()
    grad = rollout_gradient(model, solver, state, controls, loss).gradients["controls"]

    def value(c):
        states = rollout(model, solver, state, c)
        return sum(loss.stage(n, s, None).value for n, s in enumerate(states))

    e = 1e-3
    for n in (0, T - 1):
        bump = np.zeros_like(controls)
        bump[n, 0] = e
        moved = [value(controls + k * bump) for k in (0, 1, 2)]
        one_sided = (-3 * moved[0] + 4 * moved[1] - moved[2]) / (2 * e)
        assert grad[n, 0] != 0.0
        assert abs(one_sided - grad[n, 0]) <= 1e-5 * abs(grad[n, 0])
