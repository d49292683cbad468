"""pliant.diff: every gradient against central finite differences of the solvers themselves
(STYLE item 5), and the closed form of a cantilever's compliance in E.

The finite differences step the same solvers (ImplicitEuler "fresh", StaticSolver) on models
rebuilt with each parameter moved, so they check the whole chain, not the adjoint's own
formulas. Their error is O(eps^2) truncation plus round-off of the loss over eps; losses are
of displacements (not positions) to keep that round-off small.
"""

from __future__ import annotations

import importlib

import numpy as np
import pytest

from pliant.constraints.base import EmbeddedPoints
from pliant.constraints.control import DirectControl
from pliant.diff import (
    ControlPenalty,
    Losses,
    PointTracking,
    StepAdjoint,
    rollout,
    rollout_gradient,
    set_parameters,
)
from pliant.diff.elements import (
    body_shape,
    element_terms,
    frame_local_nodes,
    nodal_sum,
    rest_shape,
)
from pliant.diff.scenes import cable_beam as beam
from pliant.diff.static import static_gradient
from pliant.errors import ModelError
from pliant.solvers.implicit_euler import ImplicitEuler
from pliant.solvers.static import StaticSolver

DT = 0.01
TOL = 1e-6  # relative agreement required with central differences


def relative_error(fd: float, exact: float) -> float:
    return abs(fd - exact) / max(abs(fd), abs(exact))


def perturbed_state(model, rng, size=0.3, speed=10.0):
    state = model.rest_state()
    free = (model.body.free_index >= 0).reshape(-1, 3)
    state.positions = state.positions + size * rng.standard_normal(state.positions.shape) * free
    state.velocities = speed * rng.standard_normal(state.positions.shape) * free
    return state


@pytest.mark.parametrize("law", ["polar", "large", "neo-hookean"])
def test_element_terms_match_the_kernels(law):
    """The complex-step-safe NumPy element forces and K_s w are the compiled kernels'."""
    body = beam(law=law, tip_force=(0.0, 0.0, 0.0)).body
    rng = np.random.default_rng(0)
    x = body.rest_positions + 0.5 * rng.standard_normal(body.rest_positions.shape)
    v = rng.standard_normal(x.shape) * (body.free_index >= 0).reshape(-1, 3)
    lin = body.linearise(x, v)
    local = frame_local_nodes(body)
    forces, kv = element_terms(
        body, x[body.tets], v[body.tets], body_shape(body), local, body.mu, body.lam
    )
    scale = np.abs(lin.forces).max()
    assert np.abs(nodal_sum(body, forces) - lin.forces).max() < 1e-12 * scale
    assert np.abs(nodal_sum(body, kv) - lin.stiffness_velocity).max() < 1e-10 * np.abs(kv).max()
    shape = rest_shape(body, body.rest_positions[body.tets], local)
    assert np.allclose(shape.grads, body.grads, rtol=0, atol=1e-14)
    assert np.allclose(shape.volumes, body.volumes, rtol=1e-14)


def _one_step(model, state, commands):
    solver = ImplicitEuler(model, DT, tangent="fresh")
    return solver.step(state.copy(), DirectControl(np.array(commands, dtype=float)))


@pytest.mark.parametrize("law", ["polar", "large", "neo-hookean"])
def test_step_adjoint_against_finite_differences(law):
    """One step's VJP for every input: state, both cable modes, material, damping, density,
    load and rest shape (moved nodes)."""
    rng = np.random.default_rng(1)
    model = beam(law=law)
    # Neo-Hookean's exact tangent turns indefinite sooner under random nodal noise.
    state = perturbed_state(model, rng, size=0.05 if law == "neo-hookean" else 0.3)
    commands = [1.0, 5.0]  # top: 1 mm shortening met (tension inside bounds); bottom: 5 N
    new = _one_step(model, state, commands)
    assert 0.0 < new.actuation[0] < 1e3
    rest = model.body.rest_positions
    wq, wv = rng.standard_normal(rest.shape), 1e-2 * rng.standard_normal(rest.shape)

    def loss(s):
        return float(np.sum(wq * (s.positions - rest)) + np.sum(wv * s.velocities))

    names = (
        "controls",
        "young_modulus",
        "poisson_ratio",
        "density",
        "rayleigh_mass",
        "rayleigh_stiffness",
        "external_forces",
        "rest_positions",
    )
    grads = StepAdjoint(model, DT, state, np.array(commands), new).vjp(wq, wv, names)

    def central(fn, eps):
        return (fn(eps) - fn(-eps)) / (2.0 * eps)

    free = (model.body.free_index >= 0).reshape(-1, 3)
    for name in ("positions", "velocities"):
        d = rng.standard_normal(rest.shape) * free

        def moved(e, name=name, d=d):
            s = state.copy()
            setattr(s, name, getattr(state, name) + e * d)
            return loss(_one_step(model, s, commands))

        assert relative_error(central(moved, 1e-4), np.sum(grads[name] * d)) < TOL, name
    for i in range(2):

        def commanded(e, i=i):
            c = list(commands)
            c[i] += e
            return loss(_one_step(model, state, c))

        assert relative_error(central(commanded, 1e-3), grads["controls"][i]) < TOL
    values = {
        "young_modulus": 200.0,
        "poisson_ratio": 0.3,
        "density": 1e-6,
        "rayleigh_mass": 0.5,
        "rayleigh_stiffness": 0.01,
    }
    for name, value in values.items():

        def rebuilt(e, name=name, value=value):
            return loss(_one_step(beam(law=law, **{name: value * (1 + e)}), state, commands))

        fd = central(rebuilt, 1e-4) / value
        assert relative_error(fd, np.sum(grads[name])) < TOL, name
    tip = np.isclose(rest[:, 0], 60.0)

    def loaded(e):
        return loss(_one_step(beam(law=law, tip_force=(0.0, e, -1.0)), state, commands))

    fd = central(loaded, 1e-3)
    assert relative_error(fd, np.sum(grads["external_forces"][tip, 1]) / tip.sum()) < TOL
    d = rng.standard_normal(rest.shape)

    def reshaped(e):
        return loss(_one_step(beam(law=law, points=rest + e * d), state, commands))

    assert relative_error(central(reshaped, 1e-4), np.sum(grads["rest_positions"] * d)) < TOL


def test_displacement_command_at_its_force_bound_is_held():
    """A shortening the cable's force bound cannot deliver: the force is held at the bound,
    the command has no gradient and the step's other gradients stay exact."""
    rng = np.random.default_rng(2)
    model = beam()
    model.actuators[0].max_force = 50.0
    state = perturbed_state(model, rng, speed=0.0)
    new = _one_step(model, state, [3.0, 5.0])
    assert new.actuation[0] == 50.0
    rest = model.body.rest_positions
    w = rng.standard_normal(rest.shape)
    grads = StepAdjoint(model, DT, state, np.array([3.0, 5.0]), new).vjp(
        w, np.zeros_like(w), ("controls",)
    )
    assert grads["controls"][0] == 0.0
    d = rng.standard_normal(rest.shape) * (model.body.free_index >= 0).reshape(-1, 3)

    def moved(e):
        s = state.copy()
        s.positions = state.positions + e * d
        m = beam()
        m.actuators[0].max_force = 50.0
        return float(np.sum(w * (_one_step(m, s, [3.0, 5.0]).positions - rest)))

    fd = (moved(1e-4) - moved(-1e-4)) / 2e-4
    assert relative_error(fd, np.sum(grads["positions"] * d)) < TOL


def _tip_loss(model, n_steps):
    rest = model.body.rest_positions
    tip = EmbeddedPoints.at_nodes(np.flatnonzero(np.isclose(rest[:, 0], 60.0)))
    goal = tip.positions(rest) + np.array([0.0, 0.0, 3.0])
    return Losses(PointTracking(tip, goal, n_steps=n_steps), ControlPenalty(1e-3))


def _rollout_loss(model, controls, loss, state=None):
    solver = ImplicitEuler(model, DT, tangent="fresh")
    states = rollout(model, solver, state or model.rest_state(), controls)
    return sum(
        loss.stage(n, s, None if n == 0 else controls[n - 1]).value for n, s in enumerate(states)
    )


def test_rollout_gradient_against_finite_differences_and_checkpointing():
    """An 8-step trajectory: controls, material, damping and initial state; every
    checkpoint spacing gives the same gradient."""
    n_steps = 8
    model = beam()
    loss = _tip_loss(model, n_steps)
    controls = np.column_stack([np.linspace(0.2, 2.0, n_steps), np.full(n_steps, 5.0)])
    names = ("controls", "young_modulus", "poisson_ratio", "rayleigh_mass", "rayleigh_stiffness")
    solver = ImplicitEuler(model, DT, tangent="fresh")
    result = rollout_gradient(
        model, solver, model.rest_state(), controls, loss, wrt=names, checkpoint_every=3
    )
    assert result.value == pytest.approx(_rollout_loss(model, controls, loss), rel=1e-14)
    every = rollout_gradient(
        model, solver, model.rest_state(), controls, loss, wrt=names, checkpoint_every=1
    )
    kept = rollout_gradient(
        model, solver, model.rest_state(), controls, loss, wrt=names, checkpoint_every=n_steps
    )
    for name in names:
        assert np.allclose(every.gradients[name], result.gradients[name], rtol=1e-12, atol=0)
        assert np.allclose(kept.gradients[name], result.gradients[name], rtol=1e-12, atol=0)
    for i, j in ((0, 0), (4, 1), (7, 0)):
        moved = []
        for e in (1e-3, -1e-3):
            c = controls.copy()
            c[i, j] += e
            moved.append(_rollout_loss(model, c, loss))
        fd = (moved[0] - moved[1]) / 2e-3
        assert relative_error(fd, result.gradients["controls"][i, j]) < TOL
    values = {
        "young_modulus": 200.0,
        "poisson_ratio": 0.3,
        "rayleigh_mass": 0.5,
        "rayleigh_stiffness": 0.01,
    }
    for name, value in values.items():
        moved = [
            _rollout_loss(beam(**{name: value * (1 + e)}), controls, loss) for e in (1e-4, -1e-4)
        ]
        fd = (moved[0] - moved[1]) / (2e-4 * value)
        assert relative_error(fd, result.gradients[name]) < TOL, name
    rng = np.random.default_rng(3)
    d = rng.standard_normal((model.body.n_nodes, 3)) * (model.body.free_index >= 0).reshape(-1, 3)
    for name in ("velocities", "positions"):
        moved = []
        for e in (1e-3, -1e-3):
            s = model.rest_state()
            setattr(s, name, getattr(s, name) + e * d)
            moved.append(_rollout_loss(model, controls, loss, s))
        fd = (moved[0] - moved[1]) / 2e-3
        assert relative_error(fd, np.sum(result.gradients[f"initial_{name}"] * d)) < TOL, name


@pytest.mark.parametrize("law", ["polar", "large"])
def test_static_gradient_against_finite_differences(law):
    """The equilibrium under a cable's shortening and a tip load: command, E, density and
    rest shape by the implicit-function theorem (the large frames' tangent is not
    symmetric)."""
    rng = np.random.default_rng(4)

    def solve(model, commands):
        solver = StaticSolver(model)
        return solver, solver.step(model.rest_state(), DirectControl(np.array(commands, float)))

    commands = [1.0, 5.0]
    model = beam(law=law)
    solver, eq = solve(model, commands)
    rest = model.body.rest_positions
    w = rng.standard_normal(rest.shape)

    def loss(m, c, **kw):
        return float(np.sum(w * (solve(m, c)[1].positions - rest)))

    names = (
        "controls",
        "young_modulus",
        "poisson_ratio",
        "density",
        "external_forces",
        "rest_positions",
    )
    grads = static_gradient(model, solver, eq, np.array(commands), w, wrt=names)
    for i in range(2):
        moved = []
        for e in (1e-3, -1e-3):
            c = list(commands)
            c[i] += e
            moved.append(loss(beam(law=law), c))
        assert relative_error((moved[0] - moved[1]) / 2e-3, grads["controls"][i]) < TOL
    for name, value in (("young_modulus", 200.0), ("density", 1e-6)):
        moved = [loss(beam(law=law, **{name: value * (1 + e)}), commands) for e in (1e-4, -1e-4)]
        fd = (moved[0] - moved[1]) / (2e-4 * value)
        assert relative_error(fd, grads[name]) < TOL, name
    d = rng.standard_normal(rest.shape)
    moved = [loss(beam(law=law, points=rest + e * d), commands) for e in (1e-4, -1e-4)]
    assert relative_error((moved[0] - moved[1]) / 2e-4, np.sum(grads["rest_positions"] * d)) < TOL


def test_cantilever_compliance_in_young_modulus_closed_form():
    """A law homogeneous of degree one in E: q depends on f/E only, so
    E d delta/dE = -f . d delta/df exactly; under a small end load (linear response)
    d delta/dE = -delta/E, to the relative size of the geometric nonlinearity (~ delta/L)."""
    force = np.array([0.0, 0.0, -1e-3])
    model = beam(tip_force=force, modes=("force", "force"), density=1e-12)
    solver = StaticSolver(model)
    eq = solver.step(model.rest_state(), DirectControl(np.zeros(2)))
    rest = model.body.rest_positions
    tip = np.isclose(rest[:, 0], 60.0)
    selector = np.zeros_like(rest)
    selector[tip, 2] = 1.0 / tip.sum()  # delta: the tip's mean vertical deflection
    delta = float(np.sum(selector * (eq.positions - rest)))
    grads = static_gradient(
        model, solver, eq, np.zeros(2), selector, wrt=("young_modulus", "external_forces")
    )
    # Every load: the tip force and the (small) weight.
    loads = model.body.gravity_forces()
    loads[tip] += force / tip.sum()
    load_term = -np.sum(grads["external_forces"] * loads) / 200.0
    assert relative_error(grads["young_modulus"], load_term) < 1e-6
    assert relative_error(grads["young_modulus"], -delta / 200.0) < 10 * abs(delta) / 60.0


def test_set_parameters_and_errors():
    model = beam()
    set_parameters(model, young_modulus=[100.0, 300.0], regions=np.arange(30) % 2)
    assert model.body.mu[0] == pytest.approx(100.0 / 2.6)
    assert model.body.mu[1] == pytest.approx(300.0 / 2.6)
    solver = ImplicitEuler(model, DT, tangent="fresh")
    controls = np.zeros((2, 2))
    loss = _tip_loss(model, 2)
    with pytest.raises(ModelError, match="cannot differentiate"):
        rollout_gradient(model, solver, model.rest_state(), controls, loss, wrt=("stiffness",))
    with pytest.raises(ModelError, match="controls must be"):
        rollout_gradient(model, solver, model.rest_state(), np.zeros((2, 3)), loss)
    with pytest.raises(ModelError, match="fresh"):
        rollout_gradient(model, ImplicitEuler(model, DT), model.rest_state(), controls, loss)
    with pytest.raises(ModelError, match="regions"):
        set_parameters(model, young_modulus=1.0, regions=np.zeros(3, int))


def test_finger_rollout_gradient_against_finite_differences():
    """The coarse Soft Finger (1610 tetrahedra) closing on its cable for 3 steps: the
    effector's distance to a goal, by cable commands, E, nu and Rayleigh damping (set in place
    by set_parameters, as a calibration does)."""
    from pliant import robots

    n_steps = 3
    model = robots.soft_finger(rayleigh_mass=0.1, rayleigh_stiffness=0.01)
    points = model.effectors[0].points
    goal = points.positions(model.body.rest_positions) + np.array([0.0, 0.0, -2.0])
    loss = PointTracking(points, goal, n_steps=n_steps)
    controls = np.column_stack([np.linspace(0.5, 2.0, n_steps), np.zeros(n_steps)])
    names = ("controls", "young_modulus", "poisson_ratio", "rayleigh_mass")
    solver = ImplicitEuler(model, DT, tangent="fresh")
    result = rollout_gradient(model, solver, model.rest_state(), controls, loss, wrt=names)
    # (value, relative step): the loss's dependence on alpha is weak, and the kernels' polar
    # iteration (stopped at 1e-6 steps) leaves ~1e-12 noise in the loss: a larger step.
    base = {
        "young_modulus": (3000.0, 1e-4),
        "poisson_ratio": (0.47, 3e-5),  # lam ~ 1 / (1 - 2 nu): a smaller step near 0.5
        "rayleigh_mass": (0.1, 1e-2),
    }

    def value(c=controls, **moved):
        set_parameters(model, **moved)
        try:
            return _rollout_loss(model, c, loss)
        finally:
            set_parameters(model, **{n: v for n, (v, _) in base.items()})

    for i in (0, 2):
        moved = []
        for e in (1e-3, -1e-3):
            c = controls.copy()
            c[i, 0] += e
            moved.append(value(c))
        assert (
            relative_error((moved[0] - moved[1]) / 2e-3, result.gradients["controls"][i, 0]) < TOL
        )
    for name, (v, step) in base.items():
        moved = [value(**{name: v * (1 + e)}) for e in (step, -step)]
        fd = (moved[0] - moved[1]) / (2 * step * v)
        assert relative_error(fd, result.gradients[name]) < TOL, name


def test_calibration_recovers_the_parameters_of_a_synthetic_trajectory():
    """E, nu and both Rayleigh coefficients from every node's trajectory (15 steps of a cable
    pull), no noise, from a start 50 % to 100 % off: L-BFGS-B on the adjoint finds them to
    1e-4."""
    from pliant.diff.calibration import calibrate, observe, relative_errors

    truth = dict(young_modulus=200.0, poisson_ratio=0.3, rayleigh_mass=0.5, rayleigh_stiffness=0.01)
    start = dict(young_modulus=300.0, poisson_ratio=0.4, rayleigh_mass=1.0, rayleigh_stiffness=0.02)
    bounds = dict(
        young_modulus=(50.0, 1000.0),
        poisson_ratio=(0.05, 0.49),
        rayleigh_mass=(0.01, 5.0),
        rayleigh_stiffness=(0.001, 0.1),
    )
    n_steps = 15
    controls = np.column_stack(
        [np.minimum(np.arange(1, n_steps + 1) * 0.5, 2.0), np.full(n_steps, 5.0)]
    )
    model = beam(**truth)
    points = EmbeddedPoints.at_nodes(np.flatnonzero(model.body.free_index[::3] >= 0))
    solver = ImplicitEuler(model, DT, tangent="fresh")
    observed = observe(model, solver, model.rest_state(), controls, points)
    fitted = beam(**start)
    solver = ImplicitEuler(fitted, DT, tangent="fresh")
    result = calibrate(
        fitted, solver, fitted.rest_state(), controls, points, observed, start, bounds
    )
    errors = relative_errors(result.parameters, truth)
    assert max(errors.values()) < 1e-4, errors
    assert fitted.body.material.young_modulus == result.parameters["young_modulus"]
    with pytest.raises(ModelError, match="fits some of"):
        calibrate(
            fitted, solver, fitted.rest_state(), controls, points, observed, {"mass": 1.0}, {}
        )


def test_a_rate_limited_cable_follows_the_state():
    """With max_displacement_change binding, the target is the state's displacement plus the
    change: no gradient to the command, an exact one to the state (3 steps)."""
    n_steps = 3
    model = beam()
    model.actuators[0].max_displacement_change = 0.3
    loss = _tip_loss(model, n_steps)
    controls = np.column_stack([np.full(n_steps, 2.0), np.full(n_steps, 5.0)])
    solver = ImplicitEuler(model, DT, tangent="fresh")
    result = rollout_gradient(model, solver, model.rest_state(), controls, loss, wrt="controls")
    # Only the effort penalty's share: the command does not reach the body.
    assert np.allclose(result.gradients["controls"][:, 0], 1e-3 * controls[:, 0], rtol=1e-12)
    rng = np.random.default_rng(6)
    d = rng.standard_normal((model.body.n_nodes, 3)) * (model.body.free_index >= 0).reshape(-1, 3)
    moved = []
    for e in (1e-3, -1e-3):
        s = model.rest_state()
        s.velocities = e * d
        moved.append(_rollout_loss(model, controls, loss, s))
    fd = (moved[0] - moved[1]) / 2e-3
    assert relative_error(fd, np.sum(result.gradients["initial_velocities"] * d)) < TOL


@pytest.mark.parametrize("law", ["polar", "large"])
def test_compiled_element_gradient_matches_the_numpy_reference(law):
    """The reverse-mode kernel's gradient against complex step on the NumPy reference, and
    its unit-law terms (phi's parts linear in mu and lam) against the reference's value."""
    from pliant.diff.elements import complex_step_gradient
    from pliant.diff.kernels import corotational_adjoint_terms

    body = beam(law=law).body
    rng = np.random.default_rng(7)
    x = body.rest_positions + 0.5 * rng.standard_normal(body.rest_positions.shape)
    w, c = rng.standard_normal(x.shape), rng.standard_normal(x.shape)
    local = frame_local_nodes(body)
    a_k, h = 0.02, 0.01
    m = body.n_elements

    def value(xe, mu=body.mu, lam=body.lam):
        f, kw = element_terms(body, xe, w[body.tets], body_shape(body), local, mu, lam)
        return np.einsum("...mai,mai->...m", a_k * kw - h * f, c[body.tets])

    reference = complex_step_gradient(value, x[body.tets])
    lin = body.linearise(x)
    out, unit = np.empty_like(reference), np.empty((m, 2))
    frames = np.zeros((m, 3), np.int64) if local is None else local.astype(np.int64)
    corotational_adjoint_terms(
        x, w, c, body.tets, body.grads, body.volumes, body.mu, body.lam,
        body.material.kernel_tag, frames, body.rest_frames, lin.frames, lin.dets, a_k, h,
        out, unit,
    )  # fmt: skip
    assert np.abs(out - reference).max() < 1e-10 * np.abs(reference).max()
    active = lin.dets > 0.0
    ones, zeros = np.ones(m), np.zeros(m)
    for k, (mu, lam) in enumerate(((ones, zeros), (zeros, ones))):
        expected = np.where(active, -value(x[body.tets], mu, lam), 0.0)
        assert np.allclose(unit[:, k], expected, rtol=1e-10, atol=1e-12 * np.abs(expected).max())


def test_young_modulus_per_region_against_finite_differences():
    """E per element region (alternate elements): each region's derivative, and their sum is
    the body's."""
    n_steps = 5
    model = beam()
    regions = np.arange(model.body.n_elements) % 2
    loss = _tip_loss(model, n_steps)
    controls = np.column_stack([np.linspace(0.2, 1.0, n_steps), np.full(n_steps, 5.0)])
    solver = ImplicitEuler(model, DT, tangent="fresh")
    wrt = ("young_modulus", "poisson_ratio")
    result = rollout_gradient(
        model, solver, model.rest_state(), controls, loss, wrt=wrt, regions=regions
    )
    whole = rollout_gradient(model, solver, model.rest_state(), controls, loss, wrt=wrt)
    for name in wrt:
        assert result.gradients[name].shape == (2,)
        assert result.gradients[name].sum() == pytest.approx(whole.gradients[name], rel=1e-12)
    moved = []
    for e in (1e-2, -1e-2):
        set_parameters(model, young_modulus=[200.0, 200.0 + e], regions=regions)
        moved.append(_rollout_loss(model, controls, loss))
    fd = (moved[0] - moved[1]) / 2e-2
    assert relative_error(fd, result.gradients["young_modulus"][1]) < TOL


@pytest.mark.parametrize(("mode", "command"), [("force", 20.0), ("displacement", 50.0)])
def test_pneunet_cavity_gradient_against_finite_differences(mode, command):
    """The PneuNet's cavity (2430 tetrahedra) for 3 steps, pressure or volume commanded: the
    command and E (a cavity's rows are gradients of its volume)."""
    from pliant import robots

    n_steps = 3
    model = robots.pneunet(mesh_size=8.0)
    model.actuators[0].mode = mode
    points = model.effectors[0].points
    loss = PointTracking(points, points.positions(model.body.rest_positions) + 1.0, n_steps=n_steps)
    controls = np.full((n_steps, 1), command)
    solver = ImplicitEuler(model, DT, tangent="fresh")
    result = rollout_gradient(
        model, solver, model.rest_state(), controls, loss, wrt=("controls", "young_modulus")
    )
    moved = []
    for e in (1e-3, -1e-3):
        c = controls.copy()
        c[0, 0] += e
        moved.append(_rollout_loss(model, c, loss))
    assert relative_error((moved[0] - moved[1]) / 2e-3, result.gradients["controls"][0, 0]) < TOL
    moved = []
    for e in (1e-4, -1e-4):
        set_parameters(model, young_modulus=500.0 * (1 + e))
        moved.append(_rollout_loss(model, controls, loss))
    fd = (moved[0] - moved[1]) / (2e-4 * 500.0)
    assert relative_error(fd, result.gradients["young_modulus"]) < TOL


def test_finger_static_gradient_against_finite_differences():
    """The coarse Soft Finger's equilibrium under 3 mm of cable: the effector's position by the
    command and E (implicit-function theorem, exact tangent and the cable's geometric
    stiffness)."""
    from pliant import robots

    model = robots.soft_finger()
    points = model.effectors[0].points
    rng = np.random.default_rng(8)
    w = rng.standard_normal((len(points), 3))

    def solve(commands):
        solver = StaticSolver(model)
        eq = solver.step(model.rest_state(), DirectControl(np.array(commands, float)))
        return solver, eq, float(np.sum(w * points.positions(eq.positions)))

    commands = [3.0, 0.0]
    solver, eq, _ = solve(commands)
    grad_q = np.zeros_like(eq.positions)
    np.add.at(grad_q, points.nodes, points.weights[:, :, None] * w[:, None, :])
    grads = static_gradient(
        model, solver, eq, np.array(commands), grad_q, wrt=("controls", "young_modulus")
    )
    moved = [solve([3.0 + e, 0.0])[2] for e in (1e-3, -1e-3)]
    assert relative_error((moved[0] - moved[1]) / 2e-3, grads["controls"][0]) < TOL
    moved = []
    for e in (1e-4, -1e-4):
        set_parameters(model, young_modulus=3000.0 * (1 + e))
        moved.append(solve(commands)[2])
    set_parameters(model, young_modulus=3000.0)
    assert relative_error((moved[0] - moved[1]) / 0.6, grads["young_modulus"]) < TOL


@pytest.mark.parametrize("kept", [0, 2])
def test_gradient_with_few_or_no_factorisations_kept_is_the_same(monkeypatch, kept):
    """Where the forward steps' factorisations do not all fit (KEEP_FACTORS_BYTES), the
    adjoints of the earlier steps refactorise: the same gradient to round-off."""
    # the module (pliant.diff's own name "rollout" is the function)
    rollout_module = importlib.import_module("pliant.diff.rollout")

    n_steps = 5
    model = beam()
    loss = _tip_loss(model, n_steps)
    controls = np.column_stack([np.linspace(0.2, 1.0, n_steps), np.full(n_steps, 5.0)])
    solver = ImplicitEuler(model, DT, tangent="fresh")
    wrt = ("controls", "young_modulus")
    every = rollout_gradient(model, solver, model.rest_state(), controls, loss, wrt=wrt)
    factor_bytes = 4 * 8 * model.body.pattern.indices.size
    monkeypatch.setattr(rollout_module, "KEEP_FACTORS_BYTES", kept * factor_bytes)
    few = rollout_gradient(model, solver, model.rest_state(), controls, loss, wrt=wrt)
    for name in ("controls", "young_modulus", "initial_positions"):
        assert np.allclose(few.gradients[name], every.gradients[name], rtol=1e-10, atol=1e-14)
