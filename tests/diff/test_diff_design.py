"""Shape and routing gradients (pliant.diff.routing, pliant.diff.design): against central
differences of the solvers themselves, and the rest shape against the exact scaling law of
an equilibrium."""

from __future__ import annotations

import numpy as np
import pytest

from pliant.constraints.base import EmbeddedPoints
from pliant.constraints.control import DirectControl
from pliant.diff import PointTracking, rollout_gradient
from pliant.diff.design import RoutingDesign, optimise_routing
from pliant.diff.routing import rerouted, routing_gradient, routing_points, routing_slices
from pliant.diff.scenes import cable_beam, routing_finger
from pliant.diff.static import static_gradient
from pliant.errors import ModelError
from pliant.robots.finger import soft_finger
from pliant.solvers import ImplicitEuler, StaticSolver

TOL = 1e-6
XS = np.array([7.0, 19.0, 31.0, 43.0, 55.0])
# Two cables inside the beam's elements (not at nodes: a node's weights have no gradient).
ROUTED = np.vstack(
    [
        np.column_stack([XS, np.full(5, 2.3), 8.1 + 0.1 * np.arange(5)]),
        np.column_stack([XS + 0.4, np.full(5, 7.7), 1.9 + 0.05 * np.arange(5)]),
    ]
)


def relative_error(fd: float, exact: float) -> float:
    return abs(fd - exact) / max(abs(fd), abs(exact))


def _static(model, commands):
    solver = StaticSolver(model)
    return solver, solver.step(model.rest_state(), DirectControl(np.array(commands, float)))


def test_static_routing_gradient_against_finite_differences():
    """A displacement-mode cable (equality row) and a force-mode one: the equilibrium's
    sensitivity to every routing point, by the implicit-function theorem."""
    base = cable_beam()
    rest = base.body.rest_positions
    rng = np.random.default_rng(1)
    w = rng.standard_normal(rest.shape)
    commands = [1.0, 5.0]

    def loss(points):
        return float(np.sum(w * (_static(rerouted(base, points), commands)[1].positions - rest)))

    model = rerouted(base, ROUTED)
    solver, eq = _static(model, commands)
    grad = static_gradient(model, solver, eq, np.array(commands), w, wrt="cable_routing")
    d = rng.standard_normal(ROUTED.shape)
    fd = (loss(ROUTED + 1e-4 * d) - loss(ROUTED - 1e-4 * d)) / 2e-4
    assert relative_error(fd, np.sum(grad["cable_routing"] * d)) < TOL


def test_rollout_routing_gradient_against_finite_differences():
    """Six implicit steps under rising commands, the tip tracking a goal: the routing's share
    of every step's adjoint (the rows' values, their force and their velocity terms)."""
    base = cable_beam()
    rest = base.body.rest_positions
    tip = EmbeddedPoints.at_nodes(np.flatnonzero(rest[:, 0] == 60.0))
    n_steps = 6
    loss = PointTracking(tip, tip.positions(rest) + [0.0, 0.0, -0.5], n_steps=n_steps)
    controls = np.column_stack([np.linspace(0.2, 1.5, n_steps), np.linspace(1.0, 8.0, n_steps)])

    def run(points):
        model = rerouted(base, points)
        solver = ImplicitEuler(model, 0.01, tangent="fresh")
        return rollout_gradient(
            model, solver, model.rest_state(), controls, loss, wrt="cable_routing"
        )

    result = run(ROUTED)
    d = np.random.default_rng(2).standard_normal(ROUTED.shape)
    fd = (run(ROUTED + 1e-4 * d).value - run(ROUTED - 1e-4 * d).value) / 2e-4
    assert relative_error(fd, np.sum(result.gradients["cable_routing"] * d)) < TOL


def test_finger_routing_gradient_against_finite_differences():
    """The coarse Finger's reach for 8 mm of cable: RoutingDesign's gradient in the closing
    cable's (x, z) coordinates against central differences of its reach."""
    model, commands, free, lower, upper = routing_finger(soft_finger(gravity=(0.0, 0.0, 0.0)))
    design = RoutingDesign(model, "cable_0", commands, free=free)
    theta = design.initial + 0.5
    reach, grad = design.reach_and_gradient(theta)
    d = np.random.default_rng(3).standard_normal(theta.shape)
    fd = (design.reach(theta + 1e-4 * d) - design.reach(theta - 1e-4 * d)) / 2e-4
    assert relative_error(fd, grad @ d) < TOL
    assert (design.solves, design.adjoints) == (3, 1)
    assert reach > 40.0  # 8 mm of cable curls the finger: its tip comes down some 49 mm


def test_rest_shape_gradient_meets_the_scaling_law():
    """Scaling the rest shape by s with the same loads: the internal forces scale as s^2 and
    the weights as s^3, so q(s) = s y(s rho, f / s^2) with y the equilibrium of the unscaled
    body, exactly, for any law. For J = w.q, at s = 1:

        sum_n X_n . dJ/dX_n = J + rho dJ/drho - 2 f . dJ/df,

    the rest-shape gradient (free and held nodes) against the density and load gradients."""
    for law in ("polar", "neo-hookean"):
        model = cable_beam(law=law, modes=("force", "force"))
        rest = model.body.rest_positions
        solver, eq = _static(model, [0.0, 0.0])
        w = np.random.default_rng(4).standard_normal(rest.shape)
        grads = static_gradient(
            model,
            solver,
            eq,
            np.zeros(2),
            w,
            wrt=("rest_positions", "density", "external_forces"),
        )
        tip = np.flatnonzero(rest[:, 0] == 60.0)
        load = np.zeros_like(rest)
        load[tip] = np.array([0.0, 0.0, -1.0]) / tip.size  # cable_beam's tip load
        value = float(np.sum(w * eq.positions))
        scaling = np.sum(rest * grads["rest_positions"])
        law_side = (
            value
            + model.body.density * grads["density"]
            - 2 * np.sum(load * grads["external_forces"])
        )
        assert relative_error(scaling, law_side) < 1e-9, law


def test_routing_points_round_trip_and_errors():
    base = cable_beam()
    model = rerouted(base, ROUTED)
    assert np.allclose(routing_points(model), ROUTED, atol=1e-12)
    assert routing_slices(model) == {"top": slice(0, 5), "bottom": slice(5, 10)}
    assert model.actuators[0].rest_length == pytest.approx(
        np.sum(np.linalg.norm(np.diff(np.vstack([[-10.0, 0.0, 10.0], ROUTED[:5]]), axis=0), axis=1))
    )
    with pytest.raises(ModelError, match="routing points"):
        rerouted(base, ROUTED[:4])
    outside = ROUTED.copy()
    outside[0, 2] = 30.0
    with pytest.raises(ModelError):
        rerouted(base, outside)
    # The beam's own cables pass through nodes: no gradient there.
    with pytest.raises(ModelError, match="at nodes"):
        routing_gradient(base, base.body.rest_positions, np.ones(2))
    model, commands, free, lower, upper = routing_finger(soft_finger(gravity=(0.0, 0.0, 0.0)))
    with pytest.raises(ModelError, match="no cable"):
        RoutingDesign(model, "cable_9", commands)
    design = RoutingDesign(model, "cable_0", commands, free=free)
    with pytest.raises(ModelError, match="bounds"):
        optimise_routing(design, upper, lower)
    with pytest.raises(ModelError, match="method"):
        optimise_routing(design, lower, upper, method="TPE")


def test_nelder_mead_spends_its_budget_and_keeps_the_best():
    model, commands, free, lower, upper = routing_finger(soft_finger(gravity=(0.0, 0.0, 0.0)))
    design = RoutingDesign(model, "cable_0", commands, free=free)
    result = optimise_routing(design, lower, upper, method="Nelder-Mead", max_solves=4)
    assert (result.solves, result.adjoints) == (4, 0)
    assert len(result.history) == 4
    assert result.reach == max(r for _, r in result.history)
    assert np.all(result.theta >= lower) and np.all(result.theta <= upper)
