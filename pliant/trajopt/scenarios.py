"""Trajectory optimisation scenarios (thesis §5.2.3): problems ready for :class:`BoxDDP`.

The thesis gives no horizon, time step or weights (wave2_facts E.3 [gap]); the values here
are ours, chosen so that the goals are reachable within the bounds.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from pliant import robots
from pliant.model import Model, State
from pliant.solvers import StaticSolver
from pliant.trajopt.dynamics import CondensedDynamics, ForceControl
from pliant.trajopt.problem import ActuationBounds, QuadraticCost, tracking_cost


@dataclass
class Scenario:
    """An optimal control problem on a FEM robot."""

    name: str
    model: Model
    dynamics: CondensedDynamics
    start: State
    cost: QuadraticCost
    bounds: ActuationBounds
    goals: np.ndarray  # (N + 1, m) the position goal of each node
    controls: np.ndarray  # (n_goals, n_a) forces that hold each goal (how it was made)


@dataclass(frozen=True)
class Tracking:
    """What a goal-tracking scenario is made of, beside its robot: the time step and the
    horizon (steps), the force bounds 0 <= u <= max_force (mN) and |u_k - u_{k-1}| <=
    max_change (mN per step), the tracking cost's weights, and how long (s) each hold is
    applied to make its goal."""

    dt: float = 0.02
    horizon: int = 100
    max_force: float = 1500.0
    max_change: float = 40.0
    position_weight: float = 1.0
    velocity_weight: float = 1e-3
    control_weight: float = 1e-6
    settle: float = 3.0


def diamond_two_goals(
    *, mesh_size: float = 20.0, nonlinear: bool = False, lift: str = "pseudo-inverse", **task
) -> Scenario:
    """The Diamond's effector to two successive goals (Fig. 5.20), one per half horizon.

    The robot starts at its static equilibrium under gravity with slack cables; each goal is
    where the effector is after `settle` seconds under constant cable tensions (600, 0, 0, 200) and
    (0, 500, 400, 0) mN, so both are reachable within the bounds. `task`: the fields of
    :class:`Tracking` (defaults: its own)."""
    return _two_goals(
        "diamond",
        robots.diamond(mesh_size=mesh_size),
        np.array([[600.0, 0.0, 0.0, 200.0], [0.0, 500.0, 400.0, 0.0]]),
        replace(Tracking(), **task),
        nonlinear=nonlinear,
        lift=lift,
    )


def finger_two_goals(*, resolution: str = "coarse", **task) -> Scenario:
    """The Finger's tip to two successive goals, one per half horizon: where it is after
    `settle` seconds under cable tensions (1200, 0) mN (closing, cable 0) and (0, 1000) mN
    (opening up, cable 1), from its equilibrium under gravity with slack cables. `task`: the
    fields of :class:`Tracking` (defaults: its own, but max_force 3000 mN and max_change
    100 mN per step)."""
    return _two_goals(
        "finger",
        robots.build("finger", resolution=resolution),
        np.array([[1200.0, 0.0], [0.0, 1000.0]]),
        replace(Tracking(max_force=3000.0, max_change=100.0), **task),
    )


def trunk_reach(*, mesh_size: float = 5.2, **task) -> Scenario:
    """The Trunk's tip to one goal (reaching) over the horizon: where it is after `settle`
    seconds under cable tensions (1000, 0, 0, 600, 0, 0, 0, 0) mN (two long cables: up and
    sideways, about 30 mm from where it hangs), from its equilibrium under gravity with slack
    cables. `task`: the fields of :class:`Tracking` (defaults: its own, but horizon 50,
    max_change 100 mN per step and settle 2 s). `mesh_size` 8 gives a coarse Trunk (712
    tetrahedra) for quick runs."""
    return _two_goals(
        "trunk",
        robots.trunk(mesh_size=mesh_size, cable_mode="force"),
        np.array([[1000.0, 0.0, 0.0, 600.0, 0.0, 0.0, 0.0, 0.0]]),
        replace(Tracking(horizon=50, max_change=100.0, settle=2.0), **task),
    )


def _two_goals(
    name: str,
    model: Model,
    holds: np.ndarray,
    task: Tracking,
    *,
    nonlinear: bool = False,
    lift: str = "pseudo-inverse",
) -> Scenario:
    """Two goals, each where the effector is after `task.settle` seconds under a row of
    `holds` from the static equilibrium with no actuation (reachable by construction); one row
    of `holds` makes one goal for the whole horizon."""
    dt, horizon = task.dt, task.horizon
    n_a = model.n_actuators
    start = StaticSolver(model).step(model.rest_state(), ForceControl(np.zeros(n_a)))
    dyn = CondensedDynamics(model, dt, nonlinear=nonlinear, lift=lift)
    steps = max(1, round(task.settle / dt))
    m = dyn.n_positions
    targets = [dyn.rollout(start, np.tile(u, (steps, 1))).xs[-1, :m] for u in holds]
    goals = np.empty((horizon + 1, m))
    half = horizon // 2
    goals[: half + 1] = targets[0]
    goals[half + 1 :] = targets[-1]
    cost = tracking_cost(
        goals,
        n_controls=n_a,
        position_weight=task.position_weight,
        velocity_weight=task.velocity_weight,
        control_weight=task.control_weight,
    )
    bounds = ActuationBounds(
        np.zeros(n_a),
        np.full(n_a, task.max_force),
        max_change=np.full(n_a, task.max_change),
        previous=np.zeros(n_a),
    )
    return Scenario(name, model, dyn, start, cost, bounds, goals, holds)


SCENARIOS = {"diamond": diamond_two_goals, "finger": finger_two_goals}


def _rest_positions(model: Model, holds: np.ndarray) -> tuple[State, list[np.ndarray]]:
    """The static equilibrium with no actuation, and the effector rows where the model rests
    under each constant actuation of `holds` (reachable goals, by construction)."""
    static = StaticSolver(model)
    start = static.step(model.rest_state(), ForceControl(np.zeros(model.n_actuators)))
    dyn_rows = []
    for u in holds:
        state = static.step(model.rest_state(), ForceControl(u))
        dyn_rows.append(
            np.concatenate(
                [e.position(state.positions)[:, e.axes].reshape(-1) for e in model.effectors]
            )
        )
    return start, dyn_rows


def stiff_flop_reach(
    *,
    effector_at: str = "tip",
    dt: float = 0.05,
    horizon: int = 30,
    max_pressure_bar: float = 0.6,
    max_change_bar: float = 0.1,
    hold_kpa: tuple[float, ...] = (40.0, 0.0, 0.0, 0.0, 40.0, 0.0),
    position_weight: float = 1.0,
    velocity_weight: float = 1e-3,
    control_weight: float = 1e-5,
    mesh_size: float = 8.0,
) -> Scenario:
    """The Stiff-Flop's effector, at the tip or between the modules, to one goal (Fig. 5.21):
    where it rests under the pressures `hold_kpa` (pair 0 of the base module, pair 1 of the
    tip one: an S-bend). Pressures 0 <= p <= max_pressure_bar (bar; kPa inside), changing by at
    most `max_change_bar` per step."""
    model = robots.build("stiff_flop", mesh_size=mesh_size, effector_at=effector_at)
    holds = np.array([hold_kpa], dtype=float)
    start, targets = _rest_positions(model, holds)
    dyn = CondensedDynamics(model, dt)
    goals = np.tile(targets[0], (horizon + 1, 1))
    cost = tracking_cost(
        goals,
        n_controls=6,
        position_weight=position_weight,
        velocity_weight=velocity_weight,
        control_weight=control_weight,
    )
    kpa = 100.0 * max_pressure_bar
    bounds = ActuationBounds(
        np.zeros(6),
        np.full(6, kpa),
        max_change=np.full(6, 100.0 * max_change_bar),
        previous=np.zeros(6),
    )
    return Scenario(f"stiff_flop_{effector_at}", model, dyn, start, cost, bounds, goals, holds)


def _lianford_problem(
    name: str,
    goals: np.ndarray,
    model: Model,
    start: State,
    holds: np.ndarray,
    *,
    dt: float,
    max_torque: float,
    max_change: float,
    velocity_weight: float,
    control_weight: float,
    nonlinear: bool,
) -> Scenario:
    dyn = CondensedDynamics(model, dt, nonlinear=nonlinear, lift="static")
    cost = tracking_cost(
        goals,
        n_controls=model.n_actuators,
        velocity_weight=velocity_weight,
        control_weight=control_weight,
    )
    n_a = model.n_actuators
    bounds = ActuationBounds(
        np.full(n_a, -max_torque),
        np.full(n_a, max_torque),
        max_change=np.full(n_a, max_change),
        previous=np.zeros(n_a),
    )
    return Scenario(name, model, dyn, start, cost, bounds, goals, holds)


_LIANFORD_DEFAULTS = {
    "dt": 0.02,
    "max_torque": 5e4,
    "max_change": 5e3,
    "velocity_weight": 1e-4,
    "control_weight": 1e-9,
    "nonlinear": True,
}


def lianford_spiral(
    *,
    horizon: int = 100,
    radius: float = 3.0,
    turns: float = 1.0,
    rise: float = 0.0,
    **options,
) -> Scenario:
    """The Lianford's handle along a spiral round its rest position, a new goal every step
    (Fig. 5.22, first row): radius growing to `radius` over `turns` turns, rising `rise` (mm).
    Motor torques within +-max_torque (mN mm), changing by at most max_change per step; the
    non-linear part of Eq. 5.27 with the static lift (the probe's best on this stiff lattice)."""
    options = {**_LIANFORD_DEFAULTS, **options}
    model = robots.build("lianford", motor_mode="torque")
    start, _ = _rest_positions(model, np.zeros((0, 6)))
    x0 = CondensedDynamics(model, options["dt"]).effector_state(start)[:3]
    s = np.linspace(0.0, 1.0, horizon + 1)
    a = 2.0 * np.pi * turns * s
    goals = x0 + np.column_stack([radius * s * np.cos(a), radius * s * np.sin(a), rise * s])
    return _lianford_problem("lianford_spiral", goals, model, start, np.zeros((0, 6)), **options)


def lianford_pick_and_place(*, horizon: int = 90, **options) -> Scenario:
    """The handle back and forth between two positions (pick at A, place at B, back to A), a
    third of the horizon each (Fig. 5.22, second row); A and B are where the handle rests under
    two constant torque patterns (reachable)."""
    options = {**_LIANFORD_DEFAULTS, **options}
    model = robots.build("lianford", motor_mode="torque")
    holds = np.array([[1.2e4, 0.0, -6e3, -1.2e4, -6e3, 0.0], [-1.2e4, 6e3, 0.0, 1.2e4, 0.0, 6e3]])
    start, (a, b) = _rest_positions(model, holds)
    goals = np.empty((horizon + 1, 3))
    third = horizon // 3
    goals[: third + 1] = a
    goals[third + 1 : 2 * third + 1] = b
    goals[2 * third + 1 :] = a
    return _lianford_problem("lianford_pick_place", goals, model, start, holds, **options)


def lianford_orientation(*, horizon: int = 60, **options) -> Scenario:
    """Two effectors at once (Fig. 5.22, third row): the ring's points at +x and -x (their
    line is the handle's orientation) to where they rest under a torque pattern that tilts the
    handle about y; the handle node itself has no goal."""
    options = {**_LIANFORD_DEFAULTS, **options}
    model = robots.build("lianford", motor_mode="torque", orientation_effectors=True)
    holds = np.array([[1.0e4, 5e3, -5e3, -1.0e4, -5e3, 5e3]])
    start, (target,) = _rest_positions(model, holds)
    goals = np.tile(target, (horizon + 1, 1))
    goals[:, :3] = np.nan  # the handle: no goal
    return _lianford_problem("lianford_orientation", goals, model, start, holds, **options)


SCENARIOS.update(
    {
        "stiff-flop-tip": lambda **kw: stiff_flop_reach(effector_at="tip", **kw),
        "stiff-flop-middle": lambda **kw: stiff_flop_reach(effector_at="middle", **kw),
        "lianford-spiral": lianford_spiral,
        "lianford-pick-place": lianford_pick_and_place,
        "lianford-orientation": lianford_orientation,
    }
)
