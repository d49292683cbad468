"""What the step's overhead cuts (issue #62) keep: the compiled motion and state-equality
checks answer as numpy does, a carrier's memoised positions follow a retargeted trajectory,
and a step from a state changed in place after the last step (whose look-ahead it no longer
matches) is the step from that state, checked as one."""

from __future__ import annotations

import numpy as np
import pytest

from pliant.bench.engine import cantilever
from pliant.errors import DivergenceError, StateError
from pliant.fem.kernels import equal_2d, motion_check
from pliant.fem.rigid import DrivenNodes, KinematicBody, rail
from pliant.geometry.collision import Box
from pliant.solvers import ImplicitEuler
from pliant.solvers.base import check_motion


def test_motion_check_matches_numpy() -> None:
    rng = np.random.default_rng(0)
    x, v = rng.normal(size=(20, 3)), rng.normal(size=(20, 3))
    dq = rng.normal(size=(40, 3))[::2]  # strided, as a view may be
    assert motion_check(x, v, dq) == (True, float(np.max(np.abs(dq))))
    for bad in (np.nan, np.inf, -np.inf):
        y = v.copy()
        y[7, 2] = bad
        assert not motion_check(x, y, dq)[0]
        with pytest.raises(DivergenceError) as info:
            check_motion(x, y, dq, 10.0, 3, 0.01)
        assert info.value.cause == "non-finite"
    with pytest.raises(DivergenceError, match="moved") as info:
        check_motion(x, v, dq, 0.5 * float(np.max(np.abs(dq))), 3, 0.01)
    assert info.value.cause == "energy"
    check_motion(x, v, dq, 10.0, 3, None)  # within the body's size: no error


def test_equal_2d_matches_array_equal() -> None:
    a = np.arange(12.0).reshape(4, 3)
    b = a.copy()
    assert equal_2d(a, b) and np.array_equal(a, b)
    b[3, 1] = -b[3, 1]
    assert not equal_2d(a, b)
    a[0, 0] = b[0, 0] = np.nan
    assert equal_2d(a, b) == np.array_equal(a, b) is False
    assert equal_2d(-np.zeros((1, 3)), np.zeros((1, 3)))  # -0 == 0, as numpy says


def test_carried_positions_follow_the_carrier() -> None:
    speed = [10.0]
    cart = KinematicBody(Box([1.0, 1.0, 1.0]), rail([0, 0, 0], [1, 0, 0], lambda t: speed[0] * t))
    driver = DrivenNodes([0, 1], cart)
    driver.attach(np.array([[0.0, 0.0, 0.0], [0.0, 1.0, 0.0], [5.0, 5.0, 5.0]]))
    first = driver.positions(0.5)
    assert driver.positions(0.5) is first  # memoised
    assert not first.flags.writeable
    np.testing.assert_array_equal(first, [[5.0, 0.0, 0.0], [5.0, 1.0, 0.0]])
    speed[0] = 20.0  # the trajectory changed in place: told by forget()
    cart.forget()
    np.testing.assert_array_equal(driver.positions(0.5)[:, 0], [10.0, 10.0])
    cart.trajectory = rail([0, 0, 1], [1, 0, 0], lambda t: 0.0)  # a new trajectory: no call
    np.testing.assert_array_equal(driver.positions(0.5), [[0.0, 0.0, 1.0], [0.0, 1.0, 1.0]])


def test_step_from_a_state_changed_in_place() -> None:
    model = cantilever(1)
    solvers = [ImplicitEuler(model, 0.01), ImplicitEuler(model, 0.01)]
    states = [model.rest_state(), model.rest_state()]
    for _ in range(3):
        states = [s.step(x) for s, x in zip(solvers, states, strict=True)]
    # The first solver steps from its own last state changed in place (its look-ahead no
    # longer holds), the second from a copy: the same step.
    states[0].positions[-1, 2] += 0.5
    states[1] = states[0].copy()
    a, b = (s.step(x) for s, x in zip(solvers, states, strict=True))
    np.testing.assert_array_equal(a.positions, b.positions)
    np.testing.assert_array_equal(a.velocities, b.velocities)
    a.velocities[0, 0] = np.nan
    with pytest.raises(StateError, match="velocities holds non-finite"):
        solvers[0].step(a)
