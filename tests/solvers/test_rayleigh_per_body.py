"""Rayleigh damping per body: two disjoint beams joined in one TetBody, each with its own
alpha and beta (D = sum_i alpha_i M_i + beta_i K_i), move as each alone."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from pliant.diff.step import check_model
from pliant.errors import ModelError
from pliant.fem.body import TetBody
from pliant.fem.material import Corotational
from pliant.mesh import box_beam
from pliant.mesh.tetmesh import TetMesh
from pliant.model import Model
from pliant.solvers import ImplicitEuler

MESH = box_beam(40.0, 10.0, 10.0, 4, 1, 1)
SHIFT = np.array([0.0, 0.0, 30.0])
DAMPING = ((0.0, 0.0), (8.0, 0.02))  # beam A nearly free, beam B damped
LAW = Corotational(500.0, 0.3)
STEPS = 12


def _clamp(points: np.ndarray) -> np.ndarray:
    return np.flatnonzero(points[:, 0] <= 1e-9)


def _alone(k: int, mass: str) -> Model:
    points = MESH.points + k * SHIFT
    body = TetBody(
        TetMesh(points, MESH.tets),
        LAW,
        density=1e-3,
        mass=mass,
        fixed_nodes=_clamp(points),
        rayleigh_mass=DAMPING[k][0],
        rayleigh_stiffness=DAMPING[k][1],
    )
    return Model(body)


def _joined(mass: str, damping=DAMPING) -> Model:
    n, m = MESH.n_nodes, MESH.tets.shape[0]
    points = np.vstack([MESH.points, MESH.points + SHIFT])
    body = TetBody(
        TetMesh(points, np.vstack([MESH.tets, MESH.tets + n])),
        LAW,
        separate=True,
        density=1e-3,
        mass=mass,
        fixed_nodes=_clamp(points),
    )
    body.set_rayleigh_per_body(
        np.repeat([d[0] for d in damping], n), np.repeat([d[1] for d in damping], m)
    )
    return Model(body)


def _kick(model: Model):
    """The rest state with a bending velocity (y, growing along the beam)."""
    rest = model.rest_state()
    v = np.zeros_like(rest.velocities)
    v[:, 1] = 50.0 * model.body.rest_positions[:, 0] / 40.0
    v[model.body.free_index.reshape(-1, 3)[:, 1] < 0] = 0.0
    return dataclasses.replace(rest, velocities=v)


def _energies(model: Model, tangent: str, solver=None) -> tuple[list, object]:
    solver, state = solver or ImplicitEuler(model, 0.005, tangent=tangent), _kick(model)
    body, out = model.body, []
    for _ in range(STEPS):
        state = solver.step(state)
        kinetic = 0.5 * float(np.sum(body.node_masses[:, None] * state.velocities**2))
        out.append(kinetic + body.linearise(state.positions).energy)
    return out, state


@pytest.mark.parametrize(
    ("mass", "tangent"), [("lumped", "fresh"), ("consistent", "fresh"), ("lumped", "pcg")]
)
def test_joined_beams_move_and_lose_energy_each_as_alone(mass, tangent) -> None:
    """Each beam of the joined body ends where it ends alone (round-off), and the joined
    body's energy is the sum of the two alone, step by step: the damped beam B loses far
    more of its energy than A, each as its own damping makes it."""
    joined = _joined(mass)
    assert joined.body.rayleigh_dofs() is not None
    energy, state = _energies(joined, tangent)
    n = MESH.n_nodes
    alone = [_energies(_alone(k, mass), tangent) for k in (0, 1)]
    for k, (_, end) in enumerate(alone):
        rows = slice(k * n, (k + 1) * n)
        assert np.abs(end.positions - state.positions[rows]).max() < 1e-9
        assert np.abs(end.velocities - state.velocities[rows]).max() < 1e-7
    total = np.add(alone[0][0], alone[1][0])
    np.testing.assert_allclose(energy, total, rtol=1e-8)
    kept = [e[-1] / e[0] for e, _ in alone]
    assert kept[1] < 0.8 * kept[0]


def test_a_lagged_factorisation_is_kept_across_steps() -> None:
    """Per-DoF coefficients are the same arrays every step: the lagged policy keeps its
    factorisation (refactorising on its frames' drift, which the joined body takes over both
    beams: close to each alone, not to round-off)."""
    joined = _joined("lumped")
    solver = ImplicitEuler(joined, 0.005)
    _, state = _energies(joined, "lagged", solver)
    assert solver.system.factorisations < STEPS
    _, alone = _energies(_alone(1, "lumped"), "lagged")
    assert np.abs(alone.positions - state.positions[MESH.n_nodes :]).max() < 1e-3


def test_one_damping_for_all_keeps_the_scalar_path() -> None:
    model = _joined("lumped", damping=((0.3, 0.01), (0.3, 0.01)))
    body = model.body
    assert body.rayleigh_dofs() is None
    assert (body.rayleigh_mass, body.rayleigh_stiffness) == (0.3, 0.01)
    assert body.uniform_rayleigh("here") == (0.3, 0.01)


def test_what_takes_one_damping_refuses_per_body_damping() -> None:
    with pytest.raises(ModelError, match="pliant.diff takes one Rayleigh damping"):
        check_model(_joined("lumped"))


def test_damped_parts_must_not_share_nodes() -> None:
    body = TetBody(MESH, LAW, density=1e-6)
    beta = np.zeros(body.n_elements)
    beta[0] = 0.1
    with pytest.raises(ModelError, match="joins elements of different"):
        body.set_rayleigh_per_body(np.zeros(body.n_nodes), beta)
    with pytest.raises(ModelError, match="alpha per node"):
        body.set_rayleigh_per_body(np.zeros(3), beta)
