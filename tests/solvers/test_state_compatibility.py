"""A state that does not fit the model it enters (issue 64): the solvers and the environments'
``set_state`` refuse a state made by a model of other actuators, effectors, rigid bodies or
loads with a StateError naming the difference, also through a state file; the check costs an
identity test per step."""

from __future__ import annotations

import pickle
import time

import numpy as np
import pytest

from pliant import robots
from pliant.envs import ENVS, EnvStateError, make
from pliant.errors import StateError
from pliant.model import Model, ModelLayout, State
from pliant.solvers import ImplicitEuler, StaticSolver


@pytest.fixture(scope="module")
def diamonds() -> tuple[Model, Model]:
    """The four-cable Diamond and one of its body with two of those cables."""
    four = robots.diamond(mesh_size=20.0)
    two = Model(four.body, actuators=four.actuators[:2], name="two-cable diamond")
    return four, two


def test_a_saved_state_of_four_cables_is_refused_by_a_two_cable_model(diamonds, tmp_path):
    four, two = diamonds
    state = ImplicitEuler(four, 0.01).step(four.rest_state(), [1.0, 0.0, 0.0, 0.0])
    assert state.layout == four.layout
    path = tmp_path / "four.npz"
    state.save(path)
    loaded = State.load(path)
    assert loaded.layout == four.layout
    for solver in (ImplicitEuler(two, 0.01), StaticSolver(two)):
        with pytest.raises(StateError, match=r"actuators \[.*\] where the model has \["):
            solver.step(loaded, [0.0, 0.0])
    with pytest.raises(StateError, match="another model"):
        State.load(path, two)
    # The model's own states, saved or pickled, step on.
    ImplicitEuler(four, 0.01).step(pickle.loads(pickle.dumps(loaded)), [0.0] * 4)


def test_each_part_of_the_layout_is_named():
    base = ModelLayout(10, ("a (CableActuator)",), ("e (PositionEffector)",), ("cube",), ())
    other = ModelLayout(12, (), ("e (PositionEffector)",), (), ("SurfacePressure",))
    said = "; ".join(other.differences(base))
    for part in ("nodes 12 where the model has 10", "actuators none", "rigid bodies none"):
        assert part in said
    assert "loads ['SurfacePressure'] where the model has none" in said
    assert "effectors" not in said
    assert ModelLayout.from_json(base.to_json()) == base


def test_a_hand_made_state_is_checked_by_its_shapes_only(diamonds):
    four, _ = diamonds
    rest = four.rest_state()
    state = State(rest.positions.copy(), rest.velocities.copy())
    new = ImplicitEuler(four, 0.01).step(state, [0.0] * 4)
    assert new.layout is four.layout


def test_an_environment_refuses_a_snapshot_of_another_layout():
    env = make("pliant/Diamond-v0", **ENVS["Diamond"].quick).unwrapped
    env.reset(seed=0)
    snap = env.get_state()
    snap.state.layout = ModelLayout(snap.n_nodes, ("north (CableActuator)",))
    with pytest.raises(EnvStateError, match="actuators"):
        env.set_state(snap)


def test_the_check_costs_nothing_next_to_a_step(diamonds):
    """The model's own state: one identity test; a pickled one: a few tuple comparisons. Both
    are measured beside the step they guard, interleaved, so that a loaded machine slows both:
    the check of a pickled state costs under 2 % of a step of the quick Diamond. The check's
    cost is its fastest round of 100 (as timeit takes it: a round the scheduler interrupted
    measures the machine, not the check)."""
    four, _ = diamonds
    state = pickle.loads(pickle.dumps(four.rest_state()))
    assert state.layout is not four.layout
    solver = ImplicitEuler(four, 0.01)
    moving = solver.step(four.rest_state(), [1.0, 0.0, 0.0, 0.0])
    checks, steps = [], []
    for _ in range(7):
        start = time.perf_counter()
        for _ in range(100):
            four.check_state(state)
        checks.append((time.perf_counter() - start) / 100)
        start = time.perf_counter()
        moving = solver.step(moving, [1.0, 0.0, 0.0, 0.0])
        steps.append(time.perf_counter() - start)
    assert min(checks) < 0.02 * np.median(steps)
