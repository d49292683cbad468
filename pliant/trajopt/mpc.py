"""Receding-horizon control (MPC) on condensed dynamics, the loop closed on the full FEM.

At each control step, from the FEM state reached, the effectors' condensed dynamics are
frozen at that state (W_ea and the free motion H_e dv_free of the last FEM step, the linear
part of Eq. 5.27):

    X_{j+1} = [[I, hI], [0, I]] X_j + [W_ea; W_ea / h] u_j + [h f; f],   f = H_e dv_free,

and the box-DDP (:class:`pliant.trajopt.ddp.BoxDDP`) solves the horizon's problem on it,
warm-started by the last solution shifted by one node; the first control is applied to the
FEM, which gives the next state and the next W_ea (the step's condensed problem, no extra
solve). The prediction holds the free motion constant over the horizon, so elasticity enters
only through the loop: the thesis' perspective (§6.2.1) puts the learned condensed model in
the prediction instead.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from pliant.errors import TrajectoryOptimisationError
from pliant.model import State
from pliant.trajopt.ddp import BoxDDP
from pliant.trajopt.dynamics import CondensedDynamics
from pliant.trajopt.linear import LinearDynamics
from pliant.trajopt.problem import ActuationBounds, QuadraticCost


@dataclass
class MPCResult:
    """The closed-loop trajectory: effector states (T + 1, 2m), controls (T, n_a), the
    controller's solve time per step (s) and the FEM's step time per step (s)."""

    xs: np.ndarray
    us: np.ndarray
    solve_times: np.ndarray
    plant_times: np.ndarray
    iterations: np.ndarray

    @property
    def loop_rate(self) -> float:
        """Control steps per second of the controller alone (median solve time)."""
        return float(1.0 / np.median(self.solve_times))

    def report(self) -> dict:
        return {
            "loop_rate_hz": self.loop_rate,
            "median_solve_s": float(np.median(self.solve_times)),
            "max_solve_s": float(np.max(self.solve_times)),
            "median_fem_step_s": float(np.median(self.plant_times)),
            "closed_loop_rate_hz": float(1.0 / np.median(self.solve_times + self.plant_times)),
            "mean_ddp_iterations": float(np.mean(self.iterations)),
        }


class CondensedMPC:
    """MPC whose prediction is the condensed dynamics frozen at the current FEM state.

    Args:
        dynamics: the robot's condensed dynamics (its FEM is the plant).
        cost: the whole task's cost (its reference and weights are cut into horizons).
        bounds: actuation bounds; the change bound is measured from the control applied.
        horizon: nodes of each prediction.
        max_iterations: DDP iterations per control step (warm-started).
    """

    def __init__(
        self,
        dynamics: CondensedDynamics,
        cost: QuadraticCost,
        bounds: ActuationBounds,
        *,
        horizon: int = 20,
        max_iterations: int = 5,
    ) -> None:
        if horizon < 1:
            raise TrajectoryOptimisationError(f"the MPC horizon must be >= 1, got {horizon}")
        self.dynamics, self.cost, self.bounds = dynamics, cost, bounds
        self.horizon = int(horizon)
        self.solver = BoxDDP(max_iterations=max_iterations, tolerance=1e-6)

    def _window(self, k: int) -> QuadraticCost:
        """The task's cost over nodes k .. k + horizon (the last node repeated past the end);
        the window's last node is weighed as a running node, not the task's terminal one."""
        n = self.cost.horizon
        idx = np.minimum(np.arange(k, k + self.horizon + 1), n)
        weights = self.cost.state_weights[np.minimum(idx, n - 1)]
        return QuadraticCost(
            self.cost.state_reference[idx],
            weights,
            self.cost.control_weights,
            self.cost.control_reference,
        )

    def _prediction(self, state: State, x: np.ndarray, w_ea: np.ndarray, free: np.ndarray):
        """The horizon's model and its start from the FEM state reached (effector state x,
        W_ea and free motion of the last FEM step): here the condensed dynamics frozen there."""
        h, m = self.dynamics.dt, self.dynamics.n_positions
        eye, zero = np.eye(m), np.zeros((m, m))
        a = np.block([[eye, h * eye], [zero, eye]])
        b = np.vstack([w_ea, w_ea / h])
        drift = np.concatenate([h * free, free])
        return LinearDynamics(a, b, np.tile(drift, (self.horizon, 1))), x

    def run(self, start: State, steps: int | None = None, *, on_step=None) -> MPCResult:
        """Close the loop on the FEM from `start` for `steps` control steps (default: the
        cost's horizon)."""
        dyn = self.dynamics
        steps = self.cost.horizon if steps is None else int(steps)
        n_a, hz = dyn.n_controls, self.horizon
        previous = self.bounds.previous if self.bounds.previous is not None else np.zeros(n_a)
        # The first prediction needs a W_ea: one FEM step from the start, not applied.
        _, w_ea, free = dyn.step(start, previous)
        state = start
        xs = [dyn.effector_state(start)]
        us, solve_times, plant_times, iterations = [], [], [], []
        plan = np.tile(previous, (hz, 1))
        for k in range(steps):
            clock = time.perf_counter()
            model, x0 = self._prediction(state, xs[-1], w_ea, free)
            bounds = ActuationBounds(
                self.bounds.lower, self.bounds.upper, self.bounds.max_change, previous
            )
            result = self.solver.solve(model, x0, self._window(k), bounds, plan)
            solve_times.append(time.perf_counter() - clock)
            iterations.append(result.iterations)
            u = result.us[0]
            clock = time.perf_counter()
            state, w_ea, free = dyn.step(state, u)
            plant_times.append(time.perf_counter() - clock)
            xs.append(dyn.effector_state(state))
            us.append(u)
            previous = u
            plan = np.vstack([result.us[1:], result.us[-1:]])
            if on_step is not None:
                on_step(k, state)
        return MPCResult(
            np.array(xs),
            np.array(us),
            np.array(solve_times),
            np.array(plant_times),
            np.array(iterations),
        )
