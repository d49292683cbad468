"""First-order implicit Euler (SOFA's EulerImplicitSolver with firstOrder): M dq/dt = f(q).

Checked against the same step written out with the body's own matrices, against the static
equilibrium it must settle on (where f(q) = 0, whatever the step), and through a SOFA scene
that asks for it."""

from __future__ import annotations

import numpy as np
import pytest

from pliant.fem.material import Corotational
from pliant.model import Model
from pliant.solvers import ImplicitEuler, StaticSolver

GRAVITY = (0.0, 0.0, -9810.0)


@pytest.fixture
def beam(clamped_beam) -> Model:
    return clamped_beam(
        Corotational(200.0, 0.3), size=(60.0, 10.0, 10.0), cells=(6, 1, 1), gravity=GRAVITY
    )


def _mass_matrix(body) -> np.ndarray:
    eye = np.eye(body.n_free)
    return np.column_stack([body.mass_matvec(eye[:, k]) for k in range(body.n_free)])


def test_a_step_solves_mass_plus_h_stiffness_against_the_forces(beam):
    body, h = beam.body, 0.05
    state = beam.rest_state()
    first = ImplicitEuler(beam, h, tangent="fresh", first_order=True).step(state)
    second = ImplicitEuler(beam, h, tangent="fresh").step(state)
    # Written out: (M + h K) v = f(q) + f_g, q' = q + h v (SOFA's firstOrder step).
    lin = body.linearise(state.positions)
    k = body.stiffness_matrix(lin).toarray()
    f = body.gather(lin.forces + body.gravity_forces())
    v = np.linalg.solve(_mass_matrix(body) + h * k, f)
    assert np.allclose(body.gather(first.velocities), v, rtol=1e-9, atol=1e-12)
    assert np.allclose(body.gather(first.positions - state.positions), h * v, atol=1e-12)
    # Not the second-order step: from rest that one moves by h^2 (M + h^2 K)^-1 f.
    assert not np.allclose(first.positions, second.positions, atol=1e-6)


def test_it_settles_on_the_static_equilibrium(beam):
    static = StaticSolver(beam).step(beam.rest_state())
    solver = ImplicitEuler(beam, 0.5, first_order=True)
    state = beam.rest_state()
    for _ in range(60):
        state = solver.step(state)
    sag = np.abs(static.positions - beam.rest_state().positions).max()
    assert sag > 1.0  # a real load
    assert np.abs(state.positions - static.positions).max() < 1e-6 * sag
    assert np.abs(state.velocities).max() < 1e-6 * sag


def test_the_velocity_is_not_carried_from_one_step_to_the_next(beam, rng):
    solver = ImplicitEuler(beam, 0.01, first_order=True)
    state = solver.step(beam.rest_state())
    kicked = state.copy()
    kicked.velocities = beam.body.scatter(rng.normal(0.0, 100.0, beam.body.n_free))
    assert np.allclose(solver.step(state).positions, solver.step(kicked).positions, atol=1e-12)
