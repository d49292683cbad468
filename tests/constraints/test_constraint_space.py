"""Verification of the constraint space: Jacobians and compliance W against finite differences
and perturbed solves, the direct solve's bounds, box_qp against ProxQP, the inverse QP against
an exact active-set enumeration, and infeasible bounds."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
import scipy.sparse.linalg as spla
from conftest import MATERIALS, clamped_body, two_cable_beam

from pliant._proxsuite import proxqp
from pliant.constraints.base import EmbeddedPoints
from pliant.constraints.cable import CableActuator, CableBundle
from pliant.constraints.cavity import CavityActuator
from pliant.constraints.condensed import CondensedProblem
from pliant.constraints.direct import box_qp, solve_direct
from pliant.constraints.effector import PositionEffector
from pliant.constraints.inverse import solve_inverse
from pliant.errors import ConstraintError, InfeasibleProblemError
from pliant.mesh import TetMesh, box_beam
from pliant.model import Model
from pliant.solvers import ImplicitEuler, StaticSolver

E, NU = 1000.0, 0.3
BEAM = (60.0, 20.0, 20.0)


def _constraints(mesh: TetMesh) -> tuple[list, list]:
    """Every constraint type on a beam: a cable from a pull point behind the clamp, a cable
    anchored in the body (no pull point), a cavity (the beam's own closed surface) and a
    two-point effector on two axes. Force mode, without effort bounds (lambda of both signs)."""
    x = mesh.points
    free = {"mode": "force", "min_force": -math.inf}
    pulled = CableActuator(
        EmbeddedPoints(mesh, [[20.0, 10.0, 17.0], [40.0, 10.0, 17.0], [59.0, 10.0, 17.0]]),
        x,
        pull_point=[-10.0, 10.0, 17.0],
        name="pulled",
        **free,
    )
    anchored = CableActuator(
        EmbeddedPoints(mesh, [[5.0, 3.0, 3.0], [30.0, 3.0, 4.0], [58.0, 4.0, 3.0]]),
        x,
        name="anchored",
        **free,
    )
    cavity = CavityActuator(mesh.boundary_triangles(), x, name="cavity", **free)
    effector = PositionEffector(
        EmbeddedPoints(mesh, [[60.0, 10.0, 10.0], [45.0, 5.0, 15.0]]),
        x,
        axes=(True, False, True),
        weight=2.0,
    )
    return [pulled, anchored, cavity], [effector]


def _model(material: str = "corotational", gravity=(0.0, 0.0, 0.0), **kwargs) -> Model:
    mesh = box_beam(*BEAM, 6, 2, 2)
    body = clamped_body(mesh, MATERIALS[material](E, NU), gravity=gravity, **kwargs)
    actuators, effectors = _constraints(mesh)
    return Model(body, actuators=actuators, effectors=effectors)


def _dense_rows(constraint, x: np.ndarray) -> np.ndarray:
    """H of one constraint as a dense (rows, 3 n) matrix, from its sparse rows."""
    jac = constraint.jacobian(x)
    h = np.zeros((constraint.n_rows, x.size))
    for r in range(constraint.n_rows):
        np.add.at(h[r], (3 * jac.nodes[r][:, None] + np.arange(3)).ravel(), jac.values[r].ravel())
    return h


# ---------------------------------------------------------------------------------------------
# Jacobians


def test_every_constraint_jacobian_matches_finite_differences(rng) -> None:
    """H d = (delta(x + e d) - delta(x - e d)) / 2e + O(e^2) for each constraint type."""
    model = _model()
    x = model.body.rest_positions + 0.8 * rng.standard_normal(model.body.rest_positions.shape)
    eps = 1e-5
    for c in model.constraints:
        h = _dense_rows(c, x)
        for _ in range(3):
            d = rng.standard_normal(x.shape)
            fd = (c.distance(x + eps * d) - c.distance(x - eps * d)) / (2 * eps)
            error = np.abs(h @ d.ravel() - fd).max() / np.abs(fd).max()
            assert error < 1e-7, f"{c.name}: relative error {error:.3g}"


def test_constraint_space_matches_finite_differences_on_free_dofs(rng) -> None:
    """The assembled H^T (cables bundled, fixed DoFs dropped) against differences of every row."""
    model = _model()
    body = model.body
    x = body.rest_positions + 0.8 * rng.standard_normal(body.rest_positions.shape)
    space = model.constraint_space(x)
    expected = np.concatenate([c.distance(x) for c in model.constraints])
    assert np.allclose(space.distance, expected, rtol=0.0, atol=1e-12 * np.abs(expected).max())
    eps = 1e-5
    for _ in range(3):
        u = rng.standard_normal(body.n_free)
        d = body.scatter(u)
        fd = (model.distances(x + eps * d) - model.distances(x - eps * d)) / (2 * eps)
        error = np.abs(space.jacobian_t.T @ u - fd).max() / np.abs(fd).max()
        assert error < 1e-7, f"relative error {error:.3g}"
    assert space.slices["actuator"] == slice(0, 3)
    assert space.slices["effector"] == slice(3, 7)


# ---------------------------------------------------------------------------------------------
# Compliance W and free distance


def _perturbation_error(
    model: Model, solver, state, problem: CondensedProblem, base: np.ndarray | None = None
) -> float:
    """max over actuators i of |(delta(+lambda e_i) - delta(-lambda e_i)) / 2 - W[:, i] lambda|
    relative to max |W[:, i] lambda|, every row (actuators and effectors) compared.

    Each actuator in turn gets forces +-lambda that move its own row by 1e-3 (mm); the central
    difference cancels the O(lambda^2) curvature of delta and of the elasticity (one-sided, it
    measured 2e-4 relative), leaving O(lambda^2) ~ 1e-8."""
    n = model.n_actuators
    base = np.zeros(n) if base is None else base
    worst = 0.0
    for i in range(n):
        lam = np.zeros(n)
        lam[i] = 1e-3 / problem.compliance[i, i]
        plus = model.distances(solver.step(state.copy(), base + lam).positions)
        minus = model.distances(solver.step(state.copy(), base - lam).positions)
        change = (plus - minus) / 2.0
        predicted = problem.compliance[:, i] * lam[i]
        worst = max(worst, np.abs(change - predicted).max() / np.abs(predicted).max())
    return worst


@pytest.mark.parametrize(
    ("material", "gravity"), [("corotational", 0.0), ("neo-hookean", 0.0), ("neo-hookean", -9810.0)]
)
def test_static_compliance_predicts_perturbed_solves(material, gravity) -> None:
    """W = H K^-1 H^T at an equilibrium is the exact sensitivity d delta / d lambda.

    At rest (no preload) both tangents are exact; under gravity only Neo-Hookean's default
    tangent is exact (the corotational default R K0 R^T drops a stress term)."""
    model = _model(material, gravity=(0.0, 0.0, gravity))
    solver = StaticSolver(model)
    state = solver.step(model.rest_state(), np.zeros(3))
    problem = solver.condense(state)
    assert np.allclose(problem.free_distance, model.distances(state.positions), atol=1e-9)
    error = _perturbation_error(model, solver, state, problem)
    # Measured: 1.6e-9, 2.0e-10, 2.0e-9.
    assert error < 1e-7, f"relative error of W lambda: {error:.3g}"


def test_static_compliance_under_cable_tension_is_the_exact_sensitivity() -> None:
    """With the cables pulled hard and gravity on, the static solver's consistent tangent (the
    exact corotational tangent plus the cables' geometric stiffness lambda d^2 L/dx^2) makes
    W = H K^-1 H^T the exact d delta / d lambda; SOFA's tangent misses both terms and W is off
    by a few percent. Newton converges quadratically on the first and linearly on the second."""
    errors, iterations = {}, {}
    for consistent in (True, False):
        model = _model("corotational", gravity=(0.0, 0.0, -9810.0))
        solver = StaticSolver(model, consistent=consistent, max_iterations=300)
        tension = np.array([10000.0, 6000.0, 0.0])
        state = solver.step(model.rest_state(), tension)
        iterations[consistent] = solver.last_report.newton_iterations
        assert np.abs(state.displacement[:2]).min() > 2.0  # strongly pulled: mm of shortening
        problem = solver.condense(state)
        errors[consistent] = _perturbation_error(model, solver, state, problem, tension)
    assert errors[True] < 1e-6, errors
    assert errors[False] > 100 * errors[True], errors
    assert iterations[True] <= 8 < iterations[False], iterations


def test_cable_geometric_stiffness_matches_finite_differences(rng) -> None:
    """The blocks of the cables' geometric stiffness are -d(H^T lambda)/dx, checked column by
    column against central differences of the cable forces H^T lambda at a distorted state."""
    model = _model()
    bundle = CableBundle(model.actuators[:2])
    x = model.body.rest_positions + 0.5 * rng.standard_normal(model.body.rest_positions.shape)
    tension = np.array([2.0, 0.7])

    def forces(y: np.ndarray) -> np.ndarray:
        jac = bundle.jacobian(y)
        out = np.zeros(y.size)
        for r in range(2):
            dofs = (3 * jac.nodes[r][:, None] + np.arange(3)).ravel()
            np.add.at(out, dofs, tension[r] * jac.values[r].ravel())
        return out

    ni, nj = bundle.geometric_pairs()
    blocks = bundle.geometric_stiffness(x, tension)
    k = np.zeros((x.size, x.size))
    for e in range(ni.size):
        k[3 * ni[e] : 3 * ni[e] + 3, 3 * nj[e] : 3 * nj[e] + 3] += blocks[e]
    assert np.array_equal(k, k.T)
    eps, worst = 1e-6, 0.0
    for node in np.unique(ni):
        for axis in range(3):
            step = np.zeros_like(x)
            step[node, axis] = eps
            column = -(forces(x + step) - forces(x - step)) / (2 * eps)
            worst = max(worst, np.abs(column - k[:, 3 * node + axis]).max())
    assert worst < 1e-7 * np.abs(k).max(), worst


@pytest.mark.parametrize("embedded", [False, True])
def test_cavity_load_stiffness_matches_finite_differences(embedded, rng) -> None:
    """The pressure's load stiffness is -d(H^T lambda)/dx, H = dV/dx (V of Gauss'
    theorem), against central differences of the pressure forces at a distorted state, on
    the cavity's own nodes and on points embedded in the elements."""
    mesh = box_beam(30.0, 10.0, 10.0, 3, 1, 1)
    x0 = mesh.points
    triangles = mesh.boundary_triangles()
    points = EmbeddedPoints(mesh, 0.98 * (x0 - x0.mean(0)) + x0.mean(0)) if embedded else None
    cavity = CavityActuator(triangles, x0, points=points)
    x = x0 + 0.3 * rng.standard_normal(x0.shape)
    pressure = 1.7

    def forces(y: np.ndarray) -> np.ndarray:
        jac = cavity.jacobian(y)
        out = np.zeros(y.size)
        dofs = (3 * jac.nodes[0][:, None] + np.arange(3)).ravel()
        np.add.at(out, dofs, pressure * jac.values[0].ravel())
        return out

    ni, nj = cavity.load_stiffness_pairs()
    blocks = cavity.load_stiffness(x, pressure)
    assert blocks.shape == (ni.size, 3, 3)
    k = np.zeros((x.size, x.size))
    for e in range(ni.size):
        k[3 * ni[e] : 3 * ni[e] + 3, 3 * nj[e] : 3 * nj[e] + 3] += blocks[e]
    np.testing.assert_allclose(k, k.T, atol=1e-12 * np.abs(k).max())
    eps = 1e-6
    steps = eps * np.eye(x.size).reshape(-1, *x.shape)
    fd = np.column_stack([-(forces(x + d) - forces(x - d)) / (2 * eps) for d in steps])
    # V is cubic in x: central differences are exact up to round-off
    assert np.abs(fd - k).max() < 1e-7 * np.abs(k).max()


@pytest.mark.parametrize("material", sorted(MATERIALS))
def test_dynamic_compliance_predicts_perturbed_steps(material) -> None:
    """W = h^2 H A^-1 H^T, A = (1 + h alpha) M + (h beta + h^2) K_s: the change of every row over
    one step from a state at rest (q_free = q, so H is evaluated where delta moves)."""
    model = _model(material, rayleigh_mass=0.5, rayleigh_stiffness=0.01)
    solver = ImplicitEuler(model, 0.01, tangent="fresh")
    state = model.rest_state()
    problem = solver.condense(state)
    error = _perturbation_error(model, solver, state, problem)
    # Measured: 3.8e-9 for both materials.
    assert error < 1e-7, f"relative error of W lambda: {error:.3g}"


def test_dynamic_condense_returns_the_exact_step_problem() -> None:
    """condense(state) is the W and delta_free that a step from `state` solves with a fresh
    factorisation, whatever the solver's tangent policy."""
    model = _model("neo-hookean", gravity=(0.0, 0.0, -9810.0))
    lagged = ImplicitEuler(model, 0.01)
    state = lagged.step(model.rest_state(), np.zeros(3))
    condensed = lagged.condense(state)
    fresh = ImplicitEuler(model, 0.01, tangent="fresh")
    fresh.step(state.copy(), np.zeros(3))
    expected = fresh.last_report.problem  # a direct step holds the actuator rows only
    assert expected.compliance.shape == (model.n_actuators, model.n_actuators)
    scale = np.abs(expected.compliance).max()
    assert np.abs(condensed.block("actuator", "actuator") - expected.compliance).max() < (
        1e-10 * scale
    )
    assert np.allclose(condensed.free("actuator"), expected.free_distance, rtol=0, atol=1e-10)


def test_condensed_problems_equal_an_independent_assembly() -> None:
    """W and delta_free from sparse solves written here, at a state out of equilibrium (the rest
    state under gravity): static W = H K^-1 H^T, delta_free = delta(q) + H K^-1 r(q) with
    r = f(q) + M g; dynamic W = h^2 H A^-1 H^T, delta_free = delta(q) + h H (v + A^-1 b)."""
    model = _model("corotational", gravity=(0.0, 0.0, -9810.0), rayleigh_mass=0.3)
    body = model.body
    state = model.rest_state()
    state.velocities[:] = 1.0
    state.velocities[body.fixed_nodes] = 0.0
    q = state.positions
    lin = body.linearise(q)
    k = body.stiffness_matrix(lin).tocsc()
    ht = model.constraint_space(q).jacobian_t
    residual = body.gather(lin.forces + body.gravity_forces())

    static = StaticSolver(model).condense(state)
    k_inv = spla.spsolve(k, np.column_stack([residual, ht]))
    w = ht.T @ k_inv[:, 1:]
    assert np.abs(static.compliance - w).max() < 1e-9 * np.abs(w).max()
    free = model.distances(q) + ht.T @ k_inv[:, 0]
    assert np.allclose(static.free_distance, free, rtol=0.0, atol=1e-9)

    h, alpha = 0.01, body.rayleigh_mass
    mass = body.pattern.matrix(body.mass_data)
    a = ((1 + h * alpha) * mass + h * h * k).tocsc()
    v = body.gather(state.velocities)
    b = h * residual - h * alpha * mass @ v - h * h * (k @ v)
    a_inv = spla.spsolve(a, np.column_stack([b, ht]))
    dynamic = ImplicitEuler(model, h, tangent="fresh").condense(state)
    w = h * h * ht.T @ a_inv[:, 1:]
    assert np.abs(dynamic.compliance - w).max() < 1e-9 * np.abs(w).max()
    free = model.distances(q) + h * ht.T @ (v + a_inv[:, 0])
    assert np.allclose(dynamic.free_distance, free, rtol=0.0, atol=1e-9)


# ---------------------------------------------------------------------------------------------
# Direct solve: commands within effort and course bounds


def _cable_beam(**cable) -> Model:
    """A 60 x 10 x 10 beam (E = 100) with a cable along its top from a pull point behind the
    clamp: pulling shortens the cable (delta > 0) and bends the beam up."""
    mesh = box_beam(60.0, 10.0, 10.0, 12, 2, 2)
    x = mesh.points
    path = [[15.0, 5.0, 8.0], [30.0, 5.0, 8.0], [45.0, 5.0, 8.0], [59.0, 5.0, 8.0]]
    act = CableActuator(EmbeddedPoints(mesh, path), x, pull_point=[-10.0, 5.0, 8.0], **cable)
    eff = PositionEffector(EmbeddedPoints(mesh, [[60.0, 5.0, 5.0]]), x)
    return Model(
        clamped_body(mesh, MATERIALS["corotational"](100.0, 0.3)), actuators=[act], effectors=[eff]
    )


def _static(model: Model, command: float, steps: int = 1) -> list:
    solver, state, states = StaticSolver(model), model.rest_state(), []
    for _ in range(steps):
        state = solver.step(state, [command])
        states.append(state)
    return states


# Static steps iterate the control with Newton: at convergence the constraint holds exactly.
EXACT = 1e-8


def test_displacement_command_is_met_and_clamped_to_the_course() -> None:
    (state,) = _static(_cable_beam(mode="displacement", max_displacement=2.0), 1.5)
    assert state.displacement[0] == pytest.approx(1.5, abs=EXACT)
    assert state.actuation[0] > 0.0
    (state,) = _static(_cable_beam(mode="displacement", max_displacement=2.0), 5.0)
    assert state.displacement[0] == pytest.approx(2.0, abs=EXACT)
    model = _cable_beam(mode="displacement", min_displacement=-1.0, min_force=-math.inf)
    (state,) = _static(model, -5.0)
    assert state.displacement[0] == pytest.approx(-1.0, abs=EXACT)
    assert state.actuation[0] < 0.0


def test_effort_bound_stops_a_displacement_command() -> None:
    (free,) = _static(_cable_beam(mode="displacement"), 2.0)
    limit = 0.5 * free.actuation[0]
    (state,) = _static(_cable_beam(mode="displacement", max_force=limit), 2.0)
    assert state.actuation[0] == pytest.approx(limit, rel=1e-12)
    assert 0.0 < state.displacement[0] < 2.0
    # A cable cannot push: a negative displacement command leaves it slack (lambda = 0).
    (state,) = _static(_cable_beam(mode="displacement"), -1.0)
    assert state.actuation[0] == 0.0
    assert state.displacement[0] == pytest.approx(0.0, abs=EXACT)


def test_displacement_change_per_step_is_bounded() -> None:
    states = _static(_cable_beam(mode="displacement", max_displacement_change=0.5), 1.8, steps=5)
    reached = [s.displacement[0] for s in states]
    assert reached == pytest.approx([0.5, 1.0, 1.5, 1.8, 1.8], abs=EXACT)


def test_force_command_is_clamped_to_effort_bounds() -> None:
    (state,) = _static(_cable_beam(mode="force", max_force=3.0), 10.0)
    assert state.actuation[0] == 3.0
    (state,) = _static(_cable_beam(mode="force"), 2.0)
    assert state.actuation[0] == 2.0
    (state,) = _static(_cable_beam(mode="force"), -4.0)
    assert state.actuation[0] == 0.0
    assert state.displacement[0] == pytest.approx(0.0, abs=EXACT)


def test_force_command_is_held_at_the_course_bound() -> None:
    (free,) = _static(_cable_beam(mode="force"), 200.0)
    assert free.displacement[0] > 1.5
    (state,) = _static(_cable_beam(mode="force", max_displacement=1.0), 200.0)
    assert state.displacement[0] == pytest.approx(1.0, abs=EXACT)
    assert 0.0 < state.actuation[0] < 200.0


@pytest.mark.parametrize("mode", ["force", "displacement"])
@pytest.mark.parametrize("max_force", [110.0, math.inf])
def test_dynamic_steps_respect_bounds_in_the_linearised_problem(mode, max_force) -> None:
    """A dynamic step meets the bounds exactly on the problem it solves, the predicted
    delta = W lambda + delta_free; the state's delta differs by the linearisation error of the
    step (Taylor remainder of delta about the free configuration, 5 % measured here at
    h = 0.02; the next test checks that it vanishes with h). Holding 1.2 mm takes about 125 N,
    so an effort bound of 110 N stops the cable short of its course bound."""
    max_d, max_change = 1.2, 0.3
    model = _cable_beam(
        mode=mode, max_displacement=max_d, max_displacement_change=max_change, max_force=max_force
    )
    solver = ImplicitEuler(model, 0.02)
    state = model.rest_state()
    command = 400.0 if mode == "force" else 3.0
    for _ in range(12):
        previous = state.displacement[0]
        state = solver.step(state, [command])
        problem = solver.last_report.problem
        lam = state.actuation
        predicted = (problem.block("actuator", "actuator") @ lam + problem.free("actuator"))[0]
        assert 0.0 <= lam[0] <= max_force
        assert predicted <= max_d + 1e-9
        assert abs(predicted - previous) <= max_change + 1e-9
        assert state.displacement[0] <= 1.06 * max_d
    if math.isfinite(max_force):
        assert lam[0] == max_force
        assert state.displacement[0] < max_d
    else:
        assert state.displacement[0] == pytest.approx(max_d, rel=0.06)


def test_displacement_command_is_met_exactly_at_rest() -> None:
    """Held at a displacement command until at rest (Rayleigh damping), the cable's actual
    shortening equals the command: delta_free is linearised at the start of the step with the
    same H as W, so at rest (q_new = q) the linear prediction is the exact delta. (Evaluating
    delta at the free configuration instead left 3.4e-2 / 1.3e-2 mm at h = 0.02 / 0.01.)"""
    for h in (0.02, 0.01):
        model = _cable_beam(mode="displacement")
        model.body.rayleigh_mass = 20.0
        solver = ImplicitEuler(model, h)
        state = model.rest_state()
        for _ in range(round(2.5 / h)):
            state = solver.step(state, [1.2])
        assert np.abs(state.velocities).max() < 1e-9
        assert abs(state.displacement[0] - 1.2) < 1e-10


class _Commands:
    """Random actuators (real CableActuator objects on a two-node segment) and problems."""

    segment = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]])

    def __init__(self, rng: np.random.Generator, n: int) -> None:
        self.actuators = []
        for i in range(n):
            self.actuators.append(
                CableActuator(
                    EmbeddedPoints.at_nodes([0, 1]),
                    self.segment,
                    name=f"a{i}",
                    mode=str(rng.choice(["force", "displacement"])),
                    value=rng.uniform(-4.0, 4.0),
                    min_force=float(rng.choice([0.0, -1.0])),
                    max_force=float(rng.choice([math.inf, rng.uniform(0.5, 3.0)])),
                    min_displacement=float(rng.choice([-math.inf, rng.uniform(-3.0, -0.5)])),
                    max_displacement=float(rng.choice([math.inf, rng.uniform(0.5, 3.0)])),
                    max_displacement_change=rng.choice([None, rng.uniform(0.5, 2.0)]),
                )
            )
        j = rng.standard_normal((n, n))
        self.compliance = j @ j.T / n + 0.05 * np.eye(n)
        self.free = rng.standard_normal(n)
        self.previous = rng.standard_normal(n)

    def problem(self) -> CondensedProblem:
        n = self.free.size
        slices = {"actuator": slice(0, n), "effector": slice(n, n), "contact": slice(n, n)}
        return CondensedProblem(self.compliance, self.free, slices)

    def course(self, i: int) -> tuple[float, float]:
        a = self.actuators[i]
        lo, hi = a.min_displacement, a.max_displacement
        if a.max_displacement_change is not None:
            lo = max(lo, self.previous[i] - a.max_displacement_change)
            hi = min(hi, self.previous[i] + a.max_displacement_change)
        return lo, hi


def test_direct_solve_optimality_on_random_problems(rng) -> None:
    """Every actuator ends in one of the states the direct problem allows (tolerance 1e-8):

    displacement mode, target t = clip(command, course): delta = t, or lambda at its lower
    effort bound with delta > t, or at its upper one with delta < t (KKT of the box QP);
    force mode, c = clip(command, effort): lambda = c with delta in the course, or delta held
    at a course bound it would cross (lambda between c and the effort bound on that side), or
    lambda at that effort bound with delta still beyond the course bound."""
    tol = 1e-8
    for trial in range(400):
        case = _Commands(rng, int(rng.integers(1, 5)))
        if any(lo > hi for lo, hi in map(case.course, range(case.free.size))):
            continue
        lam = solve_direct(case.problem(), case.actuators, case.previous)
        delta = case.compliance @ lam + case.free
        # Warm-starting from last step's forces must not change the (unique) answer.
        guess = rng.uniform(-2.0, 4.0, lam.size)
        warm = solve_direct(case.problem(), case.actuators, case.previous, previous_actuation=guess)
        assert np.abs(warm - lam).max() < tol * (1.0 + np.abs(lam).max()), (trial, lam, warm)
        for i, a in enumerate(case.actuators):
            lo, hi = case.course(i)
            assert a.min_force - tol <= lam[i] <= a.max_force + tol, (trial, i)
            at_min, at_max = abs(lam[i] - a.min_force) < tol, abs(lam[i] - a.max_force) < tol
            if a.mode == "displacement":
                t = np.clip(a.value, lo, hi)
                ok = (
                    abs(delta[i] - t) < tol
                    or (at_min and delta[i] > t)
                    or (at_max and delta[i] < t)
                )
            else:
                c = np.clip(a.value, a.min_force, a.max_force)
                ok = (
                    (abs(lam[i] - c) < tol and lo - tol <= delta[i] <= hi + tol)
                    or (abs(delta[i] - hi) < tol and lam[i] <= c + tol)
                    or (abs(delta[i] - lo) < tol and lam[i] >= c - tol)
                    or (at_min and delta[i] > hi)
                    or (at_max and delta[i] < lo)
                )
            assert ok, f"trial {trial}, actuator {i} ({a.mode}): lambda {lam}, delta {delta}"


def test_force_command_at_its_effort_bound_beyond_the_course() -> None:
    """A cable commanded with its minimum force (0) whose free shortening already exceeds the
    course cannot be held (it would need to push): lambda = 0, delta = delta_free."""
    case = _Commands(np.random.default_rng(0), 1)
    act = case.actuators[0]
    act.mode, act.value = "force", 0.0
    act.min_force, act.max_force = 0.0, math.inf
    act.min_displacement, act.max_displacement = -math.inf, 1.0
    act.max_displacement_change = None
    case.compliance[:] = 2.0
    case.free[:] = 3.0
    lam = solve_direct(case.problem(), case.actuators, np.zeros(1))
    assert lam.tolist() == [0.0]


def test_held_actuator_that_coupling_pushes_below_its_course() -> None:
    """Two force-controlled actuators, W = [[1, .8], [.8, 1]], delta_free = 0. Commands 3 and -1
    (its minimum force) put both above their course (delta = 2.2 > 1, 1.4 > 1.2); holding the
    first at 1 then drops the second to 0.44, below its lower course bound 0.5, so it must be
    held there instead: W lambda = (1, 0.5) -> lambda = (5/3, -5/6), inside both effort boxes."""
    case = _Commands(np.random.default_rng(0), 2)
    for act, (value, lo, hi, dmin, dmax) in zip(
        case.actuators,
        [(3.0, 0.0, math.inf, -math.inf, 1.0), (-1.0, -1.0, 5.0, 0.5, 1.2)],
        strict=True,
    ):
        act.mode, act.value, act.min_force, act.max_force = "force", value, lo, hi
        act.min_displacement, act.max_displacement = dmin, dmax
        act.max_displacement_change = None
    case.compliance[:] = [[1.0, 0.8], [0.8, 1.0]]
    case.free[:] = 0.0
    lam = solve_direct(case.problem(), case.actuators, np.zeros(2))
    assert lam == pytest.approx([5.0 / 3.0, -5.0 / 6.0], abs=1e-12)


# ---------------------------------------------------------------------------------------------
# box_qp against ProxQP


def _proxqp_box(hess, grad, lower, upper) -> np.ndarray:
    qp = proxqp.dense.QP(grad.size, 0, 0, True)
    qp.settings.eps_abs = 1e-12
    qp.settings.eps_rel = 0.0
    big = 1e20
    qp.init(
        hess,
        grad,
        None,
        None,
        None,
        None,
        None,
        np.clip(lower, -big, big),
        np.clip(upper, -big, big),
    )
    qp.solve()
    assert qp.results.info.status == proxqp.QPSolverOutput.PROXQP_SOLVED
    return qp.results.x


def _random_box_problem(rng, n: int):
    a = rng.standard_normal((n, n))
    hess = a @ a.T + 0.1 * np.eye(n)
    grad = 3.0 * rng.standard_normal(n)
    lower = np.where(rng.random(n) < 0.3, -np.inf, rng.uniform(-2.0, 0.0, n))
    upper = np.where(rng.random(n) < 0.3, np.inf, np.maximum(lower, -2.0) + rng.uniform(0.01, 2, n))
    return hess, grad, lower, upper


def test_box_qp_equals_proxqp_on_random_problems(rng) -> None:
    """Same minimiser as ProxQP (its accuracy: 3e-8 measured at eps_abs 1e-12); box_qp's own
    answer satisfies the KKT conditions to round-off: projected gradient zero."""
    for _ in range(200):
        hess, grad, lower, upper = _random_box_problem(rng, int(rng.integers(1, 7)))
        x = box_qp(hess, grad, lower, upper)
        assert np.all(x >= lower) and np.all(x <= upper)
        assert np.abs(x - _proxqp_box(hess, grad, lower, upper)).max() < 1e-6 * (
            1 + np.abs(x).max()
        )
        g = hess @ x + grad
        projected = np.where(
            x == lower, np.minimum(g, 0), np.where(x == upper, np.maximum(g, 0), g)
        )
        assert np.abs(projected).max() < 1e-10 * (np.abs(grad).max() + np.abs(hess @ x).max())


def test_box_qp_warm_start_does_not_change_the_answer(rng) -> None:
    for _ in range(100):
        hess, grad, lower, upper = _random_box_problem(rng, int(rng.integers(1, 7)))
        cold = box_qp(hess, grad, lower, upper)
        guess = rng.uniform(-3.0, 3.0, grad.size)
        warm = box_qp(hess, grad, lower, upper, guess)
        assert np.abs(warm - cold).max() < 1e-10 * (1 + np.abs(cold).max())


def test_box_qp_with_a_pinned_variable() -> None:
    """lower == upper pins a variable; its multiplier may have either sign."""
    hess = np.array([[2.0, 0.5], [0.5, 1.0]])
    for g0 in (-3.0, 3.0):
        x = box_qp(hess, np.array([g0, -1.0]), np.array([0.0, -5.0]), np.array([0.0, 5.0]))
        assert x == pytest.approx([0.0, 1.0], abs=1e-12)


def test_box_qp_rejects_crossed_bounds() -> None:
    with pytest.raises(InfeasibleProblemError):
        box_qp(np.eye(2), np.zeros(2), np.array([0.0, 1.0]), np.array([1.0, 0.0]))


# ---------------------------------------------------------------------------------------------
# Inverse QP against an exact active-set enumeration


def _enumerated_qp(hess, grad, rows, lower, upper) -> np.ndarray:
    """Exact minimiser of 1/2 x^T H x + g^T x s.t. lower <= rows x <= upper (H positive
    definite): the optimum is the equality-constrained minimiser of some set of at most n
    active bounds; among all such points that are feasible it has the lowest objective."""
    n = grad.size
    bounds = [
        (r, b)
        for r, lo, hi in zip(rows, lower, upper, strict=True)
        for b in (lo, hi)
        if np.isfinite(b)
    ]
    best, best_value = None, np.inf
    for k in range(n + 1):
        for active in itertools.combinations(bounds, k):
            c = np.array([r for r, _ in active]).reshape(k, n)
            kkt = np.block([[hess, c.T], [c, np.zeros((k, k))]])
            rhs = np.concatenate([-grad, [b for _, b in active]])
            try:
                x = np.linalg.solve(kkt, rhs)[:n]
            except np.linalg.LinAlgError:
                continue
            y = rows @ x
            slack = 1e-9 * (1.0 + np.abs(y))
            if np.all(y >= lower - slack) and np.all(y <= upper + slack):
                value = 0.5 * x @ hess @ x + grad @ x
                if value < best_value:
                    best, best_value = x, value
    return best


def _inverse_reference(problem: CondensedProblem, actuators, previous) -> np.ndarray:
    """Eq. 2.15 as documented: min ||W_ea l + d_e||^2 + eps l^T W_aa l, eps = 1e-3
    ||W_ea^T W_ea||_F / ||W_aa||_F, effort bounds on l, course bounds on W_aa l + d_a."""
    w_ea, w_aa = problem.block("effector", "actuator"), problem.block("actuator", "actuator")
    d_e, d_a = problem.free("effector"), problem.free("actuator")
    hess = w_ea.T @ w_ea
    hess = hess + 1e-3 * np.linalg.norm(hess) / np.linalg.norm(w_aa) * w_aa
    n = len(actuators)
    lo_d = np.array([a.min_displacement for a in actuators])
    hi_d = np.array([a.max_displacement for a in actuators])
    for i, a in enumerate(actuators):
        if a.max_displacement_change is not None:
            lo_d[i] = max(lo_d[i], previous[i] - a.max_displacement_change)
            hi_d[i] = min(hi_d[i], previous[i] + a.max_displacement_change)
    rows = np.vstack([np.eye(n), w_aa])
    lower = np.concatenate([[a.min_force for a in actuators], lo_d - d_a])
    upper = np.concatenate([[a.max_force for a in actuators], hi_d - d_a])
    return _enumerated_qp(hess, w_ea.T @ d_e, rows, lower, upper)


def test_inverse_qp_equals_enumerated_optimum_on_random_problems(rng) -> None:
    segment = _Commands.segment
    checked = 0
    for _ in range(60):
        na, ne = int(rng.integers(1, 4)), 3 * int(rng.integers(1, 3))
        j = rng.standard_normal((na + ne, na + ne))
        w = j @ j.T / (na + ne)
        d = rng.standard_normal(na + ne)
        slices = {
            "actuator": slice(0, na),
            "effector": slice(na, na + ne),
            "contact": slice(na + ne, na + ne),
        }
        problem = CondensedProblem(w, d, slices)
        actuators = [
            CableActuator(
                EmbeddedPoints.at_nodes([0, 1]),
                segment,
                name=f"a{i}",
                max_force=float(rng.choice([math.inf, rng.uniform(0.5, 3.0)])),
                # Course bounds above the free displacement keep the QP feasible.
                max_displacement=float(rng.choice([math.inf, d[i] + rng.uniform(0.2, 2.0)])),
            )
            for i in range(na)
        ]
        reference = _inverse_reference(problem, actuators, np.zeros(na))
        solution = solve_inverse(problem, actuators, np.zeros(na))
        scale = 1.0 + np.abs(reference).max()
        # The QP is solved to 1e-9 (scaled); median error measured 5e-12.
        error = np.abs(solution.actuation - reference).max() / scale
        assert error < 1e-6, f"problem {checked}: lambda {solution.actuation}, exact {reference}"
        checked += 1
    assert checked == 60


def test_inverse_qp_on_a_beam_equals_enumerated_optimum() -> None:
    """Two cables (top and bottom) and a tip effector: the condensed problem of a dynamic step
    with a goal above the tip, solved by ProxQP and by enumeration."""
    model = two_cable_beam(effector_goal=[[58.0, 5.0, 15.0]])
    problem = ImplicitEuler(model, 0.05, tangent="fresh").condense(model.rest_state())
    reference = _inverse_reference(problem, model.actuators, np.zeros(2))
    solution = solve_inverse(problem, model.actuators, np.zeros(2))
    assert reference[0] > 0.0 and reference[1] == pytest.approx(0.0, abs=1e-9)
    assert np.abs(solution.actuation - reference).max() < 1e-6 * np.abs(reference).max()


# ---------------------------------------------------------------------------------------------
# Bounds that admit no solution


@pytest.mark.parametrize(
    "bounds",
    [
        {"min_force": 2.0, "max_force": 1.0},
        {"min_displacement": 1.0, "max_displacement": -1.0},
        {"max_displacement_change": 0.0},
        {"max_displacement_change": -1.0},
        {"max_force": math.nan},
        {"min_displacement": math.nan},
    ],
)
def test_crossed_or_invalid_bounds_are_rejected_at_construction(bounds) -> None:
    with pytest.raises(ConstraintError):
        CableActuator(EmbeddedPoints.at_nodes([0, 1]), _Commands.segment, **bounds)


@pytest.mark.parametrize(
    "bounds",
    [
        {"max_force": 0.0, "min_displacement": 1.0},  # may not pull, must shorten by 1
        {"max_force": 0.5, "min_displacement": 1.0},  # W_aa = 1: needs lambda >= 1
        {"max_displacement": -1.0},  # must lengthen: needs lambda < 0
    ],
)
def test_inverse_with_unreachable_course_raises(bounds) -> None:
    """W = I, delta_free = 0: the course bound on W_aa lambda conflicts with the effort bound."""
    slices = {"actuator": slice(0, 1), "effector": slice(1, 4), "contact": slice(4, 4)}
    problem = CondensedProblem(np.eye(4), np.zeros(4), slices)
    cable = CableActuator(EmbeddedPoints.at_nodes([0, 1]), _Commands.segment, **bounds)
    with pytest.raises(InfeasibleProblemError):
        solve_inverse(problem, [cable], np.zeros(1))


def test_inverse_with_an_empty_course_for_the_step_raises() -> None:
    """From delta = 0 with at most 1 per step, a course starting at 5 is out of reach."""
    slices = {"actuator": slice(0, 1), "effector": slice(1, 4), "contact": slice(4, 4)}
    problem = CondensedProblem(np.eye(4), np.zeros(4), slices)
    slow = CableActuator(
        EmbeddedPoints.at_nodes([0, 1]),
        _Commands.segment,
        min_displacement=5.0,
        max_displacement_change=1.0,
    )
    with pytest.raises(InfeasibleProblemError):
        solve_inverse(problem, [slow], np.zeros(1))


def test_malformed_constraints_are_rejected() -> None:
    mesh = box_beam(30.0, 10.0, 10.0, 3, 1, 1)
    x = mesh.points
    with pytest.raises(ConstraintError):  # one point and no pull point
        CableActuator(EmbeddedPoints.at_nodes([3]), x)
    with pytest.raises(ConstraintError):  # an open surface
        CavityActuator(mesh.boundary_triangles()[:-2], x)
    with pytest.raises(ConstraintError):  # inward normals: negative enclosed volume
        CavityActuator(mesh.boundary_triangles()[:, ::-1], x)
    with pytest.raises(ConstraintError):
        PositionEffector(EmbeddedPoints.at_nodes([3]), x, axes=(False, False, False))
    with pytest.raises(ConstraintError):
        PositionEffector(EmbeddedPoints.at_nodes([3]), x, goals=np.zeros((2, 3)))


def test_inverse_prior_decides_what_the_effectors_do_not() -> None:
    """Two actuators that move one effector by their sum (W_ea = [1, 1], W_aa = I): the
    effectors ask for lambda_1 + lambda_2 = 2 and do not say how to share it. The
    regularisation alone shares it evenly (the least force); a prior at (2, 0) takes that
    sharing at any weight, since it asks nothing the effector refuses; a prior at (0, 0)
    trades the effector's error against it, more as its weight grows."""
    w = np.array([[1.0, 0.0, 1.0], [0.0, 1.0, 1.0], [1.0, 1.0, 2.0]])
    d = np.array([0.0, 0.0, -2.0])
    slices = {"actuator": slice(0, 2), "effector": slice(2, 3), "contact": slice(3, 3)}
    problem = CondensedProblem(w, d, slices)
    actuators = [
        CableActuator(EmbeddedPoints.at_nodes([0, 1]), _Commands.segment, name=f"a{i}")
        for i in range(2)
    ]

    def solve(prior=None, weight=0.0):
        return solve_inverse(
            problem, actuators, np.zeros(2), prior=prior, prior_weight=weight
        ).actuation

    def exact(prior=(0.0, 0.0), weight=0.0):
        # 0.5 (l1 + l2 - 2)^2 + 0.5 eps |l|^2 + 0.5 rho |l - prior|^2, with eps and rho the
        # relative weights times ||W_ea^T W_ea|| = 2 over ||W_aa|| = ||W_aa^T W_aa|| = sqrt 2
        eps, rho = 1e-3 * np.sqrt(2.0), weight * np.sqrt(2.0)
        hess = np.ones((2, 2)) + (eps + rho) * np.eye(2)
        return np.linalg.solve(hess, 2.0 + rho * np.array(prior))

    np.testing.assert_allclose(solve(), exact(), atol=1e-9)
    np.testing.assert_allclose(solve(), [1.0, 1.0], atol=1e-3)  # the least force
    for weight in (0.1, 1.0, 10.0):
        np.testing.assert_allclose(solve([2.0, 0.0], weight), exact([2.0, 0.0], weight), atol=1e-9)
        np.testing.assert_allclose(solve([2.0, 0.0], weight), [2.0, 0.0], atol=1e-2 / weight)
    sums = [solve([0.0, 0.0], weight).sum() for weight in (0.1, 1.0, 10.0)]
    assert 2.0 > sums[0] > sums[1] > sums[2] > 0.0
    with pytest.raises(InfeasibleProblemError, match="prior"):
        solve([1.0, 2.0, 3.0], 1.0)


def test_inverse_control_refuses_a_bad_prior() -> None:
    from pliant.constraints.control import InverseControl
    from pliant.errors import ModelError

    model = two_cable_beam(effector_goal=[[58.0, 5.0, 15.0]])
    for prior, weight in (([1.0, 2.0, 3.0], 1.0), ([np.nan, 0.0], 1.0), ([0.0, 0.0], -1.0)):
        with pytest.raises(ModelError, match="prior"):
            InverseControl(prior=np.array(prior), prior_weight=weight).prepare(model)


def test_point_row_forms_give_each_constraints_own_jacobian(rng) -> None:
    """The solvers condense cables and effectors through their point-row forms alone (no type
    tests): G from the forms, spread over the points' nodes by their weights, is H; the cavity
    gives no form, so PointRows refuses a set that holds it."""
    from pliant.solvers.compliance import PointRows

    model = _model()
    x = model.body.rest_positions + 0.3 * rng.standard_normal(model.body.rest_positions.shape)
    pulled, anchored, cavity = model.actuators
    rows_of = [pulled, anchored, *model.effectors]
    assert cavity.point_row_form() is None
    free = model.body.free_index
    assert PointRows.build([pulled, cavity], free) is None
    rows = PointRows(rows_of, free)
    delta, g = rows.evaluate(x)
    nodes = np.concatenate([c.point_row_form().points.nodes for c in rows_of])
    weights = np.concatenate([c.point_row_form().points.weights for c in rows_of])
    h = np.zeros((rows.n_rows, x.size))
    for p in range(len(nodes)):
        for a, w in zip(nodes[p], weights[p], strict=True):
            h[:, 3 * a : 3 * a + 3] += w * g[:, 3 * p : 3 * p + 3]
    expected = np.vstack([_dense_rows(c, x) for c in rows_of])
    np.testing.assert_allclose(h, expected, atol=1e-12)
    np.testing.assert_allclose(delta, np.concatenate([c.distance(x) for c in rows_of]), atol=1e-12)
