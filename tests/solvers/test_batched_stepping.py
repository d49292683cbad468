"""Batched stepping (#24): N copies of one model in one call, equal to N single steps."""

from __future__ import annotations

import numpy as np
import pytest

from pliant import robots
from pliant.errors import SolverError, StateError
from pliant.solvers import BatchedImplicitEuler, ImplicitEuler


@pytest.fixture(scope="module")
def trunk():
    # A looser lag than the Trunk's default, so that the copies refactorise at different steps.
    return robots.trunk(lag_tolerance=0.02)


@pytest.mark.parametrize("threads", [1, 2])
def test_batch_equals_single_steps_bit_for_bit(trunk, threads) -> None:
    """Each copy under its own commands (different factorisation ages and lags) ends where a
    single solver fed the same commands does, to the last bit."""
    n, steps = 3, 12
    rng = np.random.default_rng(4)
    commands = rng.uniform(0.0, 15.0, size=(steps, n, trunk.n_actuators))
    singles = [ImplicitEuler(trunk, 0.01) for _ in range(n)]
    expected = [trunk.rest_state() for _ in range(n)]
    with BatchedImplicitEuler(trunk, n, 0.01, threads=threads) as batch:
        states = batch.rest_states()
        for k in range(steps):
            expected = [
                s.step(x, commands[k, i])
                for i, (s, x) in enumerate(zip(singles, expected, strict=True))
            ]
            states = batch.step(states, commands[k])
        factorisations = [s.system.factorisations for s in batch.solvers]
    assert len(set(factorisations)) > 1  # the copies did not refactorise together
    for got, want in zip(states, expected, strict=True):
        assert np.array_equal(got.positions, want.positions)
        assert np.array_equal(got.velocities, want.velocities)
        assert np.array_equal(got.actuation, want.actuation)
    moved = np.abs(states[0].positions - trunk.body.rest_positions).max()
    assert moved > 1.0


def test_a_failing_copy_is_reported_and_the_others_go_on(trunk) -> None:
    with BatchedImplicitEuler(trunk, 2, 0.01) as batch:
        states = batch.rest_states()
        bad = states[1].copy()
        bad.positions[0, 0] = np.nan
        out = batch.step([states[0], bad], errors="return")
        assert isinstance(out[1], StateError)
        assert np.isfinite(out[0].positions).all() and out[0].step == 1
        with pytest.raises(StateError, match="copy 1"):
            batch.step([states[0], bad])


def test_batch_arguments_are_checked(trunk) -> None:
    with pytest.raises(SolverError, match="copies"):
        BatchedImplicitEuler(trunk, 0)
    with pytest.raises(SolverError, match="threads"):
        BatchedImplicitEuler(trunk, 2, threads=0)
    with BatchedImplicitEuler(trunk, 2) as batch:
        states = batch.rest_states()
        with pytest.raises(SolverError, match="2 states"):
            batch.step(states[:1])
        with pytest.raises(SolverError, match="shape"):
            batch.step(states, np.zeros((3, trunk.n_actuators)))
        with pytest.raises(SolverError, match="errors"):
            batch.step(states, errors="ignore")
