"""The "lagged" policy's turned factorisation (LinearisedSystem._turn): a kept factorisation
turned by the nodes' best-fit rotations instead of a refactorisation, on bodies whose steps
solve no constraint columns."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import clamped_body

from pliant import robots
from pliant.fem.body import TetBody
from pliant.fem.material import Corotational
from pliant.mesh import box_beam
from pliant.model import Model
from pliant.solvers import ImplicitEuler
from pliant.solvers.system import LinearisedSystem


def _rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    k = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    cross = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + np.sin(angle) * cross + (1.0 - np.cos(angle)) * cross @ cross


def test_a_body_turned_rigidly_is_solved_exactly_without_refactorising() -> None:
    """For a free body turned rigidly (and stretched a little first), A = a M + c Q K_f Q^T
    with Q the turn: the turned factorisation Q A_f^-1 Q^T is A^-1 to round-off, and no second
    factorisation is made; without the turn the kept one is far off and is refactorised."""
    mesh = box_beam(40.0, 8.0, 8.0, nx=6, ny=2, nz=2)
    body = TetBody(mesh, Corotational(200.0, 0.4), density=1e-6)
    rest = body.rest_positions
    strained = rest * np.array([1.02, 0.99, 1.0])
    turned = (strained - rest.mean(0)) @ _rotation([1.0, 2.0, 0.5], 0.4).T
    b = np.random.default_rng(7).standard_normal(body.n_free)

    def solves(warp: bool):
        system = LinearisedSystem(body)
        system.prepare(body.linearise(strained), 1.0, 1e-4, warp=warp)
        lin = body.linearise(turned)
        system.prepare(lin, 1.0, 1e-4, warp=warp)
        return system.solve(b), system, lin

    x, system, lin = solves(True)
    assert system.factorisations == 1 and system.warps == 1
    assert np.linalg.norm(system.apply(x) - b) < 1e-9 * np.linalg.norm(b)
    unturned = system.apply(system._cholesky.solve(b)) - b
    assert np.linalg.norm(unturned) > 1e-2 * np.linalg.norm(b)
    y, plain, _ = solves(False)
    assert plain.factorisations == 2 and plain.warps == 0
    assert np.abs(x - y).max() < 1e-9 * np.abs(y).max()


@pytest.fixture(scope="module")
def swinging() -> Model:
    """A soft cantilever released under gravity across its length: it swings (7.3 mm in
    0.4 s) with no constraint rows, the case the turned factorisation is for (measured: 8
    factorisations in 40 steps plain, 2 turned; 0.48 % and 0.37 % of the motion from
    "fresh")."""
    mesh = box_beam(60.0, 10.0, 10.0, 12, 2, 2)
    return Model(clamped_body(mesh, Corotational(200.0, 0.3), gravity=(0.0, 0.0, -9810.0)))


def _run(model: Model, tangent: str, warp: bool, steps: int = 40):
    solver, state = ImplicitEuler(model, 0.01, tangent=tangent), model.rest_state()
    solver._warp = warp
    out = []
    for _ in range(steps):
        state = solver.step(state)
        out.append(state.positions.copy())
    return np.array(out), solver.system


def test_turning_keeps_the_lagged_step_within_its_accuracy_with_fewer_factorisations(
    swinging,
) -> None:
    fresh, _ = _run(swinging, "fresh", False)
    motion = np.abs(fresh - swinging.body.rest_positions).max()
    assert motion > 1.0
    plain, plain_system = _run(swinging, "lagged", False)
    turned, turned_system = _run(swinging, "lagged", True)
    assert turned_system.warps > 0
    assert turned_system.factorisations < plain_system.factorisations
    assert np.abs(turned - fresh).max() < 1e-2 * motion
    assert np.abs(plain - fresh).max() < 1e-2 * motion


def test_the_default_step_turns_only_without_constraint_rows(swinging) -> None:
    assert ImplicitEuler(swinging)._warp
    assert not ImplicitEuler(robots.build("diamond"))._warp
