"""Inverse control from a condensed model, learned or exact (thesis §5.1.2-5.1.5).

Every controller here does the same four things: get W and delta_free (from the network, or
the FEM for reference), move the effector goals (Eq. 5.6), solve the inverse QP of Eq. 2.15
for the actuator forces (ProxQP), and turn them into actuator displacements
delta_a = W_aa lambda_a + delta_a_free. The robot is then driven in displacement:

* `follow_trajectory`: the FEM robot as the plant, open loop or with the PID goal correction
  of Eq. 5.14 (thesis Fig. 5.4: learned against exact matrices); driven in displacement, or
  in force (a pressure-controlled pneumatic robot: the QP's pressures go to the plant);
* `EmbeddedController`: Algorithm 2, the network and the QP alone, no FEM in the loop, on a
  ProxQP model kept between iterations and warm-started (`WarmInverse`);
* `follow_embedded`: Algorithm 2 driving the FEM robot in force, its actuator displacements
  its own prediction (no actuator sensing: the thesis' pressure-controlled Stiff-Flop).
"""

from __future__ import annotations

import dataclasses
import math
import numbers
import time
from dataclasses import dataclass, field
from typing import Literal, Protocol

import numpy as np

from pliant._proxsuite import proxqp
from pliant.condensed.equilibrium import load_step, rest_equilibrium
from pliant.condensed.layout import ActuatorBounds, Layout
from pliant.condensed.learned import LearnedCondensedModel
from pliant.condensed.sampling import Box
from pliant.constraints.base import actuator_bounds
from pliant.constraints.condensed import CondensedProblem
from pliant.constraints.inverse import InverseSolution, solve_inverse
from pliant.errors import LearnedModelError, ModelError
from pliant.model import Model, State
from pliant.solvers import StaticSolver


class CondensedSource(Protocol):
    """Where W and delta_free come from: the layout, and the problem at a state."""

    layout: Layout

    def problem(self, state: State) -> CondensedProblem: ...


class ExactCondensed:
    """W = H K^-1 H^T and delta_free computed by the FEM at each state (the reference)."""

    def __init__(self, model: Model, solver: StaticSolver) -> None:
        self.layout = Layout.of(model)
        self.solver = solver

    def problem(self, state: State) -> CondensedProblem:
        return self.solver.condense(state)


def shift_goals(
    problem: CondensedProblem, layout: Layout, goal_rows: np.ndarray
) -> CondensedProblem:
    """Eq. 5.6: delta_e_free + p_goal^train - p_goal, the effectors moved to new goals (rows)."""
    free = problem.free_distance.copy()
    free[layout.slices["effector"]] += layout.training_goal_rows - goal_rows
    return CondensedProblem(problem.compliance, free, problem.slices)


def within(actuators: tuple[ActuatorBounds, ...], box: Box | None) -> list[ActuatorBounds]:
    """The actuators with their course narrowed to a box of displacements (e.g. the region a
    learned model covers), so that control stays where the model is valid."""
    if box is None:
        return list(actuators)
    n = len(actuators)  # the box may go on with contact rows
    return [
        dataclasses.replace(
            a,
            min_displacement=max(a.min_displacement, float(lo)),
            max_displacement=min(a.max_displacement, float(hi)),
        )
        for a, lo, hi in zip(actuators, box.low[:n], box.high[:n], strict=True)
    ]


def inverse_step(
    problem: CondensedProblem,
    layout: Layout,
    goal_rows: np.ndarray,
    actuators: list[ActuatorBounds],
    displacement: np.ndarray,
    *,
    regularisation: float = 1e-3,
) -> tuple[InverseSolution, np.ndarray]:
    """Forces of the inverse QP (Eq. 2.15) for goals moved by Eq. 5.6, and the actuator
    displacements they give, delta_a = W_aa lambda_a + delta_a_free."""
    shifted = shift_goals(problem, layout, goal_rows)
    solution = solve_inverse(
        shifted, actuators, displacement, regularisation=regularisation, course="soft"
    )
    sa = problem.slices["actuator"]
    return solution, problem.compliance[sa, sa] @ solution.actuation + problem.free_distance[sa]


class WarmInverse:
    """The inverse QP of Eq. 2.15, posed as :func:`solve_inverse` poses it, on one ProxQP model
    kept from call to call and warm-started from its previous solution.

    A control loop asks for nearly the same QP at every iteration: updating the model's data
    in place and starting from the last optimum spares the model's allocation and most of its
    iterations (in the Finger's loop, ~20 us against ~290 us for a fresh model). The optimum
    is ProxQP's, to its tolerance, without solve_inverse's active-set polish. Where ProxQP
    does not solve it (course bounds that the effort bounds cannot meet), :func:`solve_inverse`
    with soft course bounds answers instead.
    """

    BIG = 1e20  # proxsuite wants finite bounds

    def __init__(
        self,
        actuators: list[ActuatorBounds],
        *,
        regularisation: float = 1e-3,
        tolerance: float = 1e-9,
        max_iterations: int = 1000,
    ) -> None:
        n = len(actuators)
        self.actuators = actuators
        self.regularisation = regularisation
        self._qp = proxqp.dense.QP(n, 0, n, True)
        self._qp.settings.eps_abs = tolerance
        self._qp.settings.eps_rel = 0.0
        self._qp.settings.max_iter = max_iterations
        self._qp.settings.initial_guess = proxqp.InitialGuess.WARM_START_WITH_PREVIOUS_RESULT
        self._ready = False
        # bounds that do not follow the previous displacement are computed once
        self._moving = any(a.max_displacement_change is not None for a in actuators)
        self._bounds = self._finite_bounds(np.zeros(n))

    def _finite_bounds(self, previous_displacement: np.ndarray) -> tuple[np.ndarray, ...]:
        bounds = actuator_bounds(self.actuators, previous_displacement)
        return tuple(np.clip(b, -self.BIG, self.BIG) for b in bounds)

    def solve(self, problem: CondensedProblem, previous_displacement: np.ndarray) -> np.ndarray:
        """Actuator forces lambda_a minimising ||W_ea l + d_e_free||^2 + eps l^T W_aa l within
        the effort and course bounds (eps relative, as in solve_inverse)."""
        sa, se = problem.slices["actuator"], problem.slices["effector"]
        w_ea, w_aa = problem.compliance[se, sa], problem.compliance[sa, sa]
        lo, hi, dmin, dmax = (
            self._finite_bounds(previous_displacement) if self._moving else self._bounds
        )
        # in displacement units, mu = c lambda, c the mean actuator compliance (solve_inverse)
        c = float(np.mean(np.abs(np.diag(w_aa))))
        hess = w_ea.T @ w_ea
        eps = self.regularisation * np.linalg.norm(hess) / max(np.linalg.norm(w_aa), 1e-300)
        data = (
            (hess + eps * w_aa) / c**2,
            (w_ea.T @ problem.free_distance[se]) / c,
            None,
            None,
            w_aa / c,
            dmin - problem.free_distance[sa],
            dmax - problem.free_distance[sa],
            lo * c,
            hi * c,
        )
        if self._ready:
            self._qp.update(*data, update_preconditioner=False)
        else:
            self._qp.init(*data)
            self._ready = True
        self._qp.solve()
        if self._qp.results.info.status == proxqp.QPSolverOutput.PROXQP_SOLVED:
            return np.clip(self._qp.results.x / c, lo, hi)
        self._ready = False  # the next call starts afresh
        return solve_inverse(
            problem,
            self.actuators,
            previous_displacement,
            regularisation=self.regularisation,
            course="soft",
        ).actuation


@dataclass
class PID:
    """Goal correction of Eq. 5.14: p_corrected = p_goal + K e_t + I sum e + D (e_t - e_t-1),
    e_t = p_goal - p_effector, with unit steps for the sum and the difference."""

    proportional: float = 0.0
    integral: float = 0.0
    derivative: float = 0.0
    _sum: np.ndarray | None = field(default=None, init=False, repr=False)
    _previous: np.ndarray | None = field(default=None, init=False, repr=False)

    def __post_init__(self) -> None:
        for name in ("proportional", "integral", "derivative"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, numbers.Real):
                raise ModelError(f"PID gain {name} must be a real number, got {value!r}")
            if not math.isfinite(value):
                raise ModelError(f"PID gain {name} must be finite, got {value!r}")

    def correct(self, goal: np.ndarray, measured: np.ndarray) -> np.ndarray:
        error = goal - measured
        self._sum = error if self._sum is None else self._sum + error
        change = error - self._previous if self._previous is not None else np.zeros_like(error)
        self._previous = error
        return (
            goal + self.proportional * error + self.integral * self._sum + self.derivative * change
        )

    def reset(self) -> None:
        self._sum = self._previous = None


@dataclass
class TrajectoryResult:
    """Goals and the effector positions the FEM robot reached, one row per goal."""

    goals: np.ndarray
    reached: np.ndarray
    displacements: np.ndarray

    @property
    def errors(self) -> np.ndarray:
        """Euclidean distance between goal and reached effector position, per goal."""
        return np.linalg.norm(self.reached - self.goals, axis=-1).max(axis=1)


def effector_positions(model: Model, state: State) -> np.ndarray:
    """Every effector point's position, (points, 3) in effector order."""
    return np.vstack([e.position(state.positions) for e in model.effectors])


def follow_trajectory(
    model: Model,
    goals: np.ndarray,
    source: CondensedSource,
    *,
    iterations: int = 5,
    pid: PID | None = None,
    course: Box | None = None,
    max_increment: float = 8.0,
    tolerance: float = 1e-8,
    regularisation: float = 1e-3,
    drive: Literal["displacement", "force"] = "displacement",
) -> TrajectoryResult:
    """Drive the FEM robot through `goals` with condensed matrices from `source`.

    For each goal, `iterations` times: W and delta_free at the robot's state, the goal moved
    by Eq. 5.6 (corrected by `pid` from the measured effector, Eq. 5.14, if given), the QP,
    and the resulting actuator displacements imposed on the FEM robot (load stepped); with
    `drive="force"`, the QP's actuator forces instead (pressure control).

    Args:
        goals: (n, 3) for a single effector point, or (n, points, 3).
        course: a box of actuator displacements the controller keeps to.
        max_increment, tolerance: the plant's load stepping (`load_step`, in the units of
            the commands it is driven with) and Newton tolerance (relative to the body size).
    """
    layout = source.layout
    layout.check(model)
    goals = _goal_points(goals)
    solver = StaticSolver(model, tolerance=tolerance, max_iterations=60)
    state = rest_equilibrium(model, solver)
    actuators = within(layout.actuators, course)
    reached, displacements = [], []
    for goal in goals:
        goal_rows = layout.effector_rows(goal)
        for _ in range(iterations):
            target = goal_rows
            if pid is not None:
                target = pid.correct(
                    goal_rows, layout.effector_rows(effector_positions(model, state))
                )
            solution, displacement = inverse_step(
                source.problem(state),
                layout,
                target,
                actuators,
                state.displacement,
                regularisation=regularisation,
            )
            command = displacement if drive == "displacement" else solution.actuation
            state = load_step(model, solver, state, command, max_increment, mode=drive)
        reached.append(effector_positions(model, state))
        displacements.append(state.displacement)
    return TrajectoryResult(goals, np.array(reached), np.array(displacements))


def follow_embedded(
    model: Model,
    goals: np.ndarray,
    controller: EmbeddedController,
    *,
    iterations: int = 5,
    closed_loop: bool = False,
    max_increment: float = 8.0,
    tolerance: float = 1e-8,
) -> TrajectoryResult:
    """Drive the FEM robot, pressure-controlled, through `goals` with Algorithm 2.

    For each goal, `iterations` controller steps; each one's actuator forces lambda_a are
    imposed on the FEM robot (load stepped in force), while the controller queries its model
    at its own delta_a = W_aa lambda_a + delta_a_free (no actuator sensing). Closed loop, its
    PID reads the FEM's effector; open loop, the model's prediction of it.

    Args:
        max_increment, tolerance: the plant's force load stepping (`load_step`) and Newton
            tolerance (relative to the body size).
    """
    controller.layout.check(model)
    goals = _goal_points(goals)
    solver = StaticSolver(model, tolerance=tolerance, max_iterations=60)
    state = rest_equilibrium(model, solver)
    reached, displacements = [], []
    for goal in goals:
        for _ in range(iterations):
            measured = effector_positions(model, state) if closed_loop else None
            controller.step(goal, measured)
            state = load_step(
                model, solver, state, controller.actuation, max_increment, mode="force"
            )
        reached.append(effector_positions(model, state))
        displacements.append(state.displacement)
    return TrajectoryResult(goals, np.array(reached), np.array(displacements))


def _goal_points(goals: np.ndarray) -> np.ndarray:
    """Goals as (n, points, 3), from (n, 3) for a single effector point."""
    goals = np.asarray(goals, dtype=float)
    return goals.reshape(len(goals), -1, 3)


class EmbeddedController:
    """Algorithm 2: closed-loop control from the learned model and a QP alone, no FEM.

    Starts at lambda_a = 0, delta_a = delta_a_free of the rest values. Each `step`: correct
    the goal from the measured effector (PID, Eq. 5.14, if given), predict W and delta_free
    at delta_a, solve the QP for lambda_a, update delta_a = W_aa lambda_a + delta_a_free.
    Without a sensor, the model's own prediction of the effector stands for it.
    """

    def __init__(
        self,
        learned: LearnedCondensedModel,
        *,
        pid: PID | None = None,
        regularisation: float = 1e-3,
        course: Box | None = None,
    ) -> None:
        self.learned = learned
        self.layout = learned.layout
        self.pid = pid
        self.regularisation = regularisation
        self.actuators = within(
            self.layout.actuators, learned.input_box if course is None else course
        )
        self.qp = WarmInverse(self.actuators, regularisation=regularisation)
        rest = learned.layout.unpack(*learned.rest)
        self.displacement = rest.free("actuator").copy()
        self.actuation = np.zeros(self.layout.counts["actuator"])
        self.effector_rows = rest.free("effector") + self.layout.training_goal_rows

    def step(self, goal: np.ndarray, measured: np.ndarray | None = None) -> np.ndarray:
        """One loop iteration for an effector goal (points, 3) and, optionally, the measured
        effector positions; returns the actuator displacements to apply."""
        measured_rows = None if measured is None else self.layout.effector_rows(measured)
        return self.step_rows(self.layout.effector_rows(goal), measured_rows)

    def step_rows(
        self, goal_rows: np.ndarray, measured_rows: np.ndarray | None = None
    ) -> np.ndarray:
        """`step` with goals and measurements already in effector rows."""
        if self.pid is not None:
            seen = self.effector_rows if measured_rows is None else measured_rows
            goal_rows = self.pid.correct(goal_rows, seen)
        problem = shift_goals(self.learned.predict(self.displacement), self.layout, goal_rows)
        self.actuation = self.qp.solve(problem, self.displacement)
        sa, se = problem.slices["actuator"], problem.slices["effector"]
        self.displacement = problem.compliance[sa, sa] @ self.actuation + problem.free_distance[sa]
        # the goal-shifted delta_e is p - goal (Eq. 5.6)
        self.effector_rows = (
            problem.compliance[se, sa] @ self.actuation + problem.free_distance[se] + goal_rows
        )
        return self.displacement


def loop_frequency(
    controller: EmbeddedController, goals: np.ndarray, iterations: int = 1000
) -> float:
    """Loop iterations per second of the embedded controller cycling through `goals`."""
    if iterations < 1:
        raise LearnedModelError(f"iterations must be >= 1, got {iterations}")
    rows = [
        controller.layout.effector_rows(g)
        for g in np.asarray(goals, dtype=float).reshape(len(goals), -1, 3)
    ]
    start = time.perf_counter()
    for k in range(iterations):
        controller.step_rows(rows[k % len(rows)])
    return iterations / (time.perf_counter() - start)
