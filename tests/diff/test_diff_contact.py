"""Contact and friction in the gradients (pliant.diff.contact): a cantilever whose tip sags onto
a floor and is dragged along it by its cables, against central differences of the solvers
themselves, where no contact changes state under the perturbation: the rollout with and
without friction, the static equilibrium frictionless, with its contacts sticking and, its
slip measured over the solve, sliding."""

from __future__ import annotations

import numpy as np
import pytest

from pliant.constraints.base import EmbeddedPoints
from pliant.constraints.control import DirectControl
from pliant.diff import PointTracking, rollout, rollout_gradient
from pliant.diff.contact import closed_contacts, held_contacts
from pliant.diff.scenes import beam_on_floor
from pliant.diff.static import static_gradient
from pliant.errors import ModelError
from pliant.solvers import ImplicitEuler, StaticSolver

TOL = 1e-6
N_STEPS = 8
CONTROLS = np.column_stack([np.linspace(0.0, 0.2, N_STEPS), np.linspace(0.4, 2.0, N_STEPS)])


def relative_error(fd: float, exact: float) -> float:
    return abs(fd - exact) / max(abs(fd), abs(exact))


def _loss():
    rest = beam_on_floor().body.rest_positions
    tip = EmbeddedPoints.at_nodes(np.flatnonzero(rest[:, 0] >= 48.0))
    return PointTracking(tip, tip.positions(rest) + [-1.0, 0.0, -0.5], n_steps=N_STEPS)


LOSS = _loss()


def _run(model, controls=CONTROLS, state=None):
    loss = LOSS
    solver = ImplicitEuler(model, 0.01, tangent="fresh")
    state = model.rest_state() if state is None else state
    return rollout_gradient(
        model,
        solver,
        state,
        controls,
        loss,
        wrt=("controls", "young_modulus", "rest_positions", "friction"),
    )


def _states(model):
    """(closed, sticking, sliding) contacts of every step of the rollout."""
    states = rollout(
        model, ImplicitEuler(model, 0.01, tangent="fresh"), model.rest_state(), CONTROLS
    )
    held = [held_contacts(model, 0.01, a, b) for a, b in zip(states[:-1], states[1:], strict=True)]
    return [(0, 0, 0) if h is None else (h.closed, h.sticking, h.sliding) for h in held]


@pytest.mark.parametrize("friction", [0.0, 0.3, 3.0])
def test_rollout_gradient_with_contacts_against_finite_differences(friction):
    """Frictionless contacts; one corner sticking, the other sliding, then both sliding;
    both sticking, then one: the commands, E, the rest shape, the friction coefficient and
    the initial velocities."""
    model = beam_on_floor(friction=friction)
    counts = np.array(_states(model))
    assert counts[:, 0].max() >= 2  # the tip's corners rest on the floor
    if friction == 0.3:
        assert counts[:, 1].max() == 1 and counts[:, 2].max() == 2
    if friction == 3.0:
        assert counts[:, 1].max() == 2 and counts[:, 2].max() >= 1
    result = _run(model)
    grads = result.gradients
    rng = np.random.default_rng(0)
    d = rng.standard_normal(CONTROLS.shape)
    fd = (_run(model, CONTROLS + 1e-5 * d).value - _run(model, CONTROLS - 1e-5 * d).value) / 2e-5
    assert relative_error(fd, np.sum(grads["controls"] * d)) < TOL
    moved = [
        _run(beam_on_floor(friction=friction, young_modulus=200.0 * (1 + e))).value
        for e in (1e-5, -1e-5)
    ]
    assert relative_error((moved[0] - moved[1]) / 4e-3, grads["young_modulus"]) < TOL
    rest = model.body.rest_positions
    d = rng.standard_normal(rest.shape)
    # The rest state moves with the rest shape: both gradients.
    moved = [
        _run(beam_on_floor(friction=friction, points=rest + e * d)).value for e in (1e-5, -1e-5)
    ]
    exact = np.sum((grads["rest_positions"] + grads["initial_positions"]) * d)
    assert relative_error((moved[0] - moved[1]) / 2e-5, exact) < TOL
    if friction > 0.0:  # the coefficient: the sliding contacts' share
        moved = [_run(beam_on_floor(friction=friction * (1 + e))).value for e in (1e-5, -1e-5)]
        exact = grads["friction"][0]
        assert relative_error((moved[0] - moved[1]) / (2e-5 * friction), exact) < TOL
    free = (model.body.free_index >= 0).reshape(-1, 3)
    dv = rng.standard_normal(rest.shape) * free
    moved = []
    for e in (1e-3, -1e-3):  # a small gradient: a larger step keeps round-off below 1e-6
        state = model.rest_state()
        state.velocities = e * dv
        moved.append(_run(model, state=state).value)
    exact = np.sum(grads["initial_velocities"] * dv)
    assert relative_error((moved[0] - moved[1]) / 2e-3, exact) < TOL


def _static(model, commands):
    solver = StaticSolver(model)
    return solver, solver.step(model.rest_state(), DirectControl(np.array(commands, float)))


def test_static_gradient_with_frictionless_contacts_against_finite_differences():
    """The beam's equilibrium with two tip corners on the floor (their gaps held closed): the
    commands, E and the rest shape by the implicit-function theorem."""
    model = beam_on_floor(friction=0.0)
    rest = model.body.rest_positions
    commands = [0.3, 2.0]
    solver, eq = _static(model, commands)
    assert np.count_nonzero(eq.contact_forces.forces[:, 2] > 0.0) == 2
    w = np.random.default_rng(1).standard_normal(rest.shape)

    def loss(m, c):
        return float(np.sum(w * (_static(m, c)[1].positions - rest)))

    names = ("controls", "young_modulus", "rest_positions")
    grads = static_gradient(model, solver, eq, np.array(commands), w, wrt=names)
    for i in range(2):
        moved = [loss(model, np.add(commands, np.eye(2)[i] * e)) for e in (1e-4, -1e-4)]
        assert relative_error((moved[0] - moved[1]) / 2e-4, grads["controls"][i]) < TOL
    moved = [
        loss(beam_on_floor(friction=0.0, young_modulus=200.0 * (1 + e)), commands)
        for e in (1e-5, -1e-5)
    ]
    assert relative_error((moved[0] - moved[1]) / 4e-3, grads["young_modulus"]) < TOL
    d = np.random.default_rng(2).standard_normal(rest.shape)
    moved = [
        loss(beam_on_floor(friction=0.0, points=rest + e * d), commands) for e in (1e-5, -1e-5)
    ]
    exact = np.sum(grads["rest_positions"] * d)
    assert relative_error((moved[0] - moved[1]) / 2e-5, exact) < TOL


def test_static_gradient_with_sticking_contacts_against_finite_differences():
    """The beam dragged along the floor (its tip corners sliding to the friction cone), then
    its drag eased from there: both corners stick, their points held. The derivative of that
    second equilibrium, solved from the first, against central differences of the same
    restarted solve: the commands and E (the friction coefficient, away from the cone, 0)."""
    model = beam_on_floor(friction=3.0)
    rest = model.body.rest_positions
    _, dragged = _static(model, [0.3, 2.0])
    commands = np.array([0.3, 1.7])

    def settle(m, c):
        return StaticSolver(m).step(dragged, DirectControl(np.asarray(c, float)))

    eq = settle(model, commands)
    held = closed_contacts(model, eq)
    assert (held.closed, held.sticking) == (2, 2)
    w = np.random.default_rng(1).standard_normal(rest.shape)

    def loss(m, c):
        return float(np.sum(w * (settle(m, c).positions - rest)))

    grads = static_gradient(
        model, StaticSolver(model), eq, commands, w, wrt=("controls", "young_modulus", "friction")
    )
    for i, h in ((0, 1e-6), (1, 1e-4)):  # a larger step in the first eases a corner off stick
        moved = [loss(model, commands + np.eye(2)[i] * e) for e in (h, -h)]
        assert relative_error((moved[0] - moved[1]) / (2 * h), grads["controls"][i]) < TOL
    moved = [
        loss(beam_on_floor(friction=3.0, young_modulus=200.0 * (1 + e)), commands)
        for e in (1e-5, -1e-5)
    ]
    assert relative_error((moved[0] - moved[1]) / 4e-3, grads["young_modulus"]) < TOL
    np.testing.assert_array_equal(grads["friction"], [0.0])


def test_static_gradient_with_sliding_contacts_against_finite_differences():
    """The beam dragged along the floor from rest, its slip measured over the whole solve
    (StaticSolver(slip="solve")): both tip corners slide, on the cone, against their slip from
    the start. Their friction's turning with the slip included, the derivative of the solve
    from rest against central differences of it: commands, E, the friction coefficient, and
    the rest shape (the start being the rest state: its cotangent added)."""
    model = beam_on_floor(friction=0.3)
    rest, start = model.body.rest_positions, model.rest_state()
    commands = np.array([0.3, 2.0])

    def solve(m, c, s=start):
        return StaticSolver(m, slip="solve").step(s, DirectControl(np.asarray(c, float)))

    eq = solve(model, commands)
    held = closed_contacts(model, eq, start)
    assert (held.closed, held.sticking, held.sliding) == (2, 0, 2)
    # The solve's friction opposes each point's tangential motion over the whole solve.
    contact = model.contacts.constraint(eq.positions, None)
    forces = eq.contact_forces.warm_start(contact.contacts).reshape(-1, 3)
    closed = forces[:, 0] > 0.0
    points = model.contacts.points
    moved = points.positions(eq.positions) - points.positions(start.positions)
    tangents = contact.contacts.frames[closed, 1:]
    slip = np.einsum("krj,kj->kr", tangents, moved[contact.contacts.index_a[closed]])
    along = forces[closed, 1:] / np.linalg.norm(forces[closed, 1:], axis=1)[:, None]
    np.testing.assert_allclose(along, -slip / np.linalg.norm(slip, axis=1)[:, None], atol=1e-8)
    w = np.random.default_rng(1).standard_normal(rest.shape)

    def loss(m, c=commands, s=start):
        return float(np.sum(w * (solve(m, c, s).positions - rest)))

    names = ("controls", "young_modulus", "friction", "rest_positions")
    grads = static_gradient(
        model, StaticSolver(model, slip="solve"), eq, commands, w, wrt=names, start=start
    )
    for i in range(2):
        moved = [loss(model, commands + np.eye(2)[i] * e) for e in (1e-4, -1e-4)]
        assert relative_error((moved[0] - moved[1]) / 2e-4, grads["controls"][i]) < TOL
    moved = [loss(beam_on_floor(young_modulus=200.0 * (1 + e))) for e in (1e-5, -1e-5)]
    assert relative_error((moved[0] - moved[1]) / 4e-3, grads["young_modulus"]) < TOL
    moved = [loss(beam_on_floor(friction=0.3 + e)) for e in (1e-5, -1e-5)]
    assert relative_error((moved[0] - moved[1]) / 2e-5, grads["friction"][0]) < TOL
    d = np.random.default_rng(2).standard_normal(rest.shape)
    moved = []
    for e in (1e-5, -1e-5):
        m = beam_on_floor(points=rest + e * d)
        moved.append(loss(m, s=m.rest_state()))
    exact = np.sum((grads["rest_positions"] + grads["start_positions"]) * d)
    assert relative_error((moved[0] - moved[1]) / 2e-5, exact) < TOL


def test_static_gradient_refuses_sliding_contacts_and_friction_at_frictionless_ones():
    model = beam_on_floor(friction=0.3)
    solver, eq = _static(model, [0.3, 2.0])  # dragged: both corners slide, on the cone
    with pytest.raises(ModelError, match="2 of 2 closed contacts slide.*slip='solve'"):
        static_gradient(model, solver, eq, np.array([0.3, 2.0]), np.zeros_like(eq.positions))
    with pytest.raises(ModelError, match="start= is the state"):
        static_gradient(
            model, solver, eq, np.array([0.3, 2.0]), np.zeros_like(eq.positions), start=eq
        )
    with pytest.raises(ModelError, match="needs start="):
        static_gradient(
            model, StaticSolver(model, slip="solve"), eq, np.array([0.3, 2.0]), eq.positions
        )
    with pytest.raises(ModelError, match="slip must be"):
        StaticSolver(model, slip="update")
    model = beam_on_floor(friction=0.0)
    solver, eq = _static(model, [0.3, 2.0])
    with pytest.raises(ModelError, match="frictionless closed contact"):
        static_gradient(
            model, solver, eq, np.array([0.3, 2.0]), np.zeros_like(eq.positions), wrt="friction"
        )
