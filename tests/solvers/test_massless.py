"""Massless bodies (mass="none", SOFA's body with no mass component): M = 0 and no weight, so
the implicit step (h beta + h^2) K_s (v + dv) = h f moves the body by h / (h + beta) K_s^-1 f,
a Newton step towards its static equilibrium damped by Rayleigh's beta.

Checked against that step written out with the body's own matrices, against the static
equilibrium it settles on, and through the errors of what a massless body cannot do."""

from __future__ import annotations

import numpy as np
import pytest

from pliant.diff.step import check_has_mass
from pliant.errors import MaterialError, ModelError
from pliant.fem.body import TetBody
from pliant.fem.hexbody import HexBody
from pliant.fem.loads import NodalForces
from pliant.fem.material import Corotational
from pliant.mesh import box_beam
from pliant.mesh.hexmesh import regular_grid
from pliant.model import Model
from pliant.solvers import ImplicitEuler, StaticSolver

H = 0.01


def _beam(**kwargs) -> Model:
    """A massless cantilever (60 x 10 x 10 mm, clamped at x = 0) with a load on its tip face
    large enough to bend it well beyond the linear range."""
    mesh = box_beam(60.0, 10.0, 10.0, 6, 1, 1)
    x = mesh.points
    tip = np.flatnonzero(x[:, 0] >= x[:, 0].max() - 1e-9)
    body = TetBody(
        mesh,
        Corotational(200.0, 0.3),
        mass="none",
        fixed_nodes=np.flatnonzero(x[:, 0] <= 1e-9),
        gravity=(0.0, 0.0, -9810.0),
        loads=[NodalForces(tip, [0.0, 0.0, -20.0])],
        **kwargs,
    )
    return Model(body, name="massless beam")


@pytest.fixture(scope="module")
def equilibrium() -> np.ndarray:
    model = _beam()
    return StaticSolver(model).step(model.rest_state()).positions


def test_a_massless_body_weighs_nothing():
    body = _beam().body
    assert body.massless and body.total_mass == 0.0 and body.density == 0.0
    assert not np.any(body.gravity_forces())
    assert not np.any(body.mass_matvec(np.ones(body.n_free)))


@pytest.mark.parametrize("beta", [0.0, 0.05])
def test_a_step_is_a_damped_newton_step(beta):
    model = _beam(rayleigh_stiffness=beta)
    body = model.body
    # From a moving state (the first step's): its velocity must not count.
    state = ImplicitEuler(model, H, tangent="fresh").step(model.rest_state())
    after = ImplicitEuler(model, H, tangent="fresh").step(state)
    lin = body.linearise(state.positions)
    k = body.stiffness_matrix(lin).toarray()
    f = body.gather(lin.forces)
    dx = H / (H + beta) * np.linalg.solve(k, f)
    moved = body.gather(after.positions - state.positions)
    assert np.abs(moved).max() > 1e-3  # the body moves: the check is not vacuous
    np.testing.assert_allclose(moved, dx, rtol=1e-8, atol=1e-10 * np.abs(dx).max())
    # The velocity it leaves is that step over h: none of the start velocity survives.
    np.testing.assert_allclose(body.gather(after.velocities), dx / H, rtol=1e-8, atol=1e-8)


def test_without_damping_the_first_step_is_newtons_first_iterate():
    model = _beam()
    body = model.body
    rest = model.rest_state()
    step = ImplicitEuler(model, H, tangent="fresh").step(rest)
    lin = body.linearise(rest.positions)
    newton = np.linalg.solve(body.stiffness_matrix(lin).toarray(), body.gather(lin.forces))
    np.testing.assert_allclose(body.gather(step.positions - rest.positions), newton, rtol=1e-9)


@pytest.mark.parametrize(("beta", "first_order"), [(0.0, False), (0.02, False), (0.02, True)])
def test_steps_settle_on_the_static_equilibrium(equilibrium, beta, first_order):
    model = _beam(rayleigh_stiffness=beta)
    sim = ImplicitEuler(model, H, tangent="fresh", first_order=first_order)
    state = model.rest_state()
    for _ in range(60):
        state = sim.step(state)
    tip = np.abs(equilibrium - model.body.rest_positions).max()
    assert tip > 5.0  # bent well beyond the linear range
    np.testing.assert_allclose(state.positions, equilibrium, atol=1e-6 * tip)


def test_a_massless_body_free_to_move_is_refused():
    mesh = box_beam(60.0, 10.0, 10.0, 6, 1, 1)
    model = Model(TetBody(mesh, Corotational(200.0, 0.3), mass="none"), name="loose")
    with pytest.raises(ModelError, match="loose's body has no mass and is free to move"):
        ImplicitEuler(model, H)


def test_a_massless_body_takes_no_density_nor_masses():
    mesh = box_beam(60.0, 10.0, 10.0, 6, 1, 1)
    with pytest.raises(MaterialError, match="massless body"):
        TetBody(mesh, Corotational(200.0, 0.3), mass="none", density=1e-6)
    body = _beam().body
    with pytest.raises(ModelError, match="no node masses"):
        body.set_node_masses(np.ones(body.n_nodes))
    with pytest.raises(ModelError, match="no density to differentiate"):
        check_has_mass(body)


def test_a_massless_hexahedral_body_settles_on_its_equilibrium():
    mesh = regular_grid((4, 2, 2), (0.0, 0.0, 0.0), (40.0, 10.0, 10.0))
    x = mesh.points
    body = HexBody(
        mesh,
        Corotational(200.0, 0.3),
        mass="none",
        fixed_nodes=np.flatnonzero(x[:, 0] < 0.1),
        loads=[NodalForces(np.flatnonzero(x[:, 0] > 39.9), [0.0, 0.0, -5.0])],
        gravity=(0.0, 0.0, -9810.0),
    )
    model = Model(body, name="massless grid")
    assert body.massless and not np.any(body.gravity_forces())
    sim, state = ImplicitEuler(model, H, tangent="fresh"), model.rest_state()
    for _ in range(20):
        state = sim.step(state)
    equilibrium = StaticSolver(model).step(model.rest_state()).positions
    tip = np.abs(equilibrium - x).max()
    assert tip > 1.0
    np.testing.assert_allclose(state.positions, equilibrium, atol=1e-9 * tip)
