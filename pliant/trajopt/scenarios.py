"""Trajectory optimisation scenarios (thesis §5.2.3): problems ready for :class:`BoxDDP`.

The thesis gives no horizon, time step or weights (wave2_facts E.3 [gap]); the values here
are ours, chosen so that the goals are reachable within the bounds.
"""

from __future__ import annotations

from dataclasses import dataclass

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


def diamond_two_goals(
    *,
    mesh_size: float = 20.0,
    dt: float = 0.02,
    horizon: int = 100,
    nonlinear: bool = False,
    lift: str = "pseudo-inverse",
    max_force: float = 1500.0,
    max_change: float = 40.0,
    position_weight: float = 1.0,
    velocity_weight: float = 1e-3,
    control_weight: float = 1e-6,
    settle: float = 3.0,
) -> Scenario:
    """The Diamond's effector to two successive goals (Fig. 5.20), one per half horizon.

    The robot starts at its static equilibrium under gravity with slack cables; each goal is
    where the effector is after `settle` seconds under constant cable tensions (600, 0, 0, 200) and
    (0, 500, 400, 0) mN, so both are reachable within the bounds 0 <= u <= max_force (mN),
    |u_k - u_{k-1}| <= max_change (mN per step)."""
    model = robots.diamond(mesh_size=mesh_size)
    start = StaticSolver(model).step(model.rest_state(), ForceControl(np.zeros(4)))
    dyn = CondensedDynamics(model, dt, nonlinear=nonlinear, lift=lift)
    holds = np.array([[600.0, 0.0, 0.0, 200.0], [0.0, 500.0, 400.0, 0.0]])
    steps = max(1, round(settle / dt))
    targets = [dyn.rollout(start, np.tile(u, (steps, 1))).xs[-1, :3] for u in holds]
    goals = np.empty((horizon + 1, 3))
    half = horizon // 2
    goals[: half + 1] = targets[0]
    goals[half + 1 :] = targets[1]
    cost = tracking_cost(
        goals,
        n_controls=4,
        position_weight=position_weight,
        velocity_weight=velocity_weight,
        control_weight=control_weight,
    )
    bounds = ActuationBounds(
        np.zeros(4), np.full(4, max_force), max_change=np.full(4, max_change), previous=np.zeros(4)
    )
    return Scenario("diamond", model, dyn, start, cost, bounds, goals, holds)


SCENARIOS = {"diamond": diamond_two_goals}
