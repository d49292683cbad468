"""Condensed dynamics of the effectors (thesis §5.2.1, Eq. 5.21-5.27), read from the FEM.

The state of the optimal control problem is X = [p; p_dot], the positions and velocities of
the effector rows, and its control u the actuator forces lambda_a. One implicit Euler step
(:mod:`pliant.solvers.implicit_euler`) moves the nodes by h (v + dv) with
dv = dv_free + h A^-1 H_a^T u, so that, with Pliant's W_ea = h^2 H_e A^-1 H_a^T (W already
carries h^2; the thesis' W_ea does not),

    p_{k+1}     = p_k + h p_dot_k + h H_e dv_free + W_ea u_k                       (Eq. 5.24)
    p_dot_{k+1} = p_dot_k + H_e dv_free + (W_ea / h) u_k

and the control derivative (Eq. 5.26) is exact: df/du = [W_ea; W_ea / h].

The state derivative (Eq. 5.27) has a linear part [[I, hI], [0, I]], which needs nothing but
the rollout, and a non-linear part, the response of the free motion to the state through the
stiffness and damping in A. Lifting a change of the effector state onto the nodes by a map L
with H_e L = I, the exact derivative of one step (A frozen over the step, K_s = -df/dx,
A = a_m M + a_k K_s) is

    d p'/d p     = I - h^2 S,   d p'/d p_dot     = h P,
    d p_dot'/d p = -h S,        d p_dot'/d p_dot = P,

with P = H_e A^-1 M L and S = H_e A^-1 K_s L = (I - a_m P) / a_k: the thesis' Eq. 5.27 with
K and D written out. Two lifts:

* "pseudo-inverse", L = H_e^+ (the thesis uses H_e^T, H_e's pseudo-inverse for points at
  nodes): the effector's own nodes move, a dent that the stiffness snaps back within a step;
* "compliance", L = A^-1 H_e^T (H_e A^-1 H_e^T)^-1: the shape the body takes under a force at
  the effector over one step;
* "static", L = K^-1 H_e^T (H_e K^-1 H_e^T)^-1 with K the stiffness at the rollout's start
  (one more factorisation per rollout): the shape of a quasi-static push on the effector,
  the effector's own mass-spring (Guyan's reduction onto the effector).

Each needs one or two solves of as many columns as effector rows per step.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pliant.constraints.condensed import CondensedProblem
from pliant.constraints.effector import PositionEffector
from pliant.errors import DivergenceError, ModelError
from pliant.model import Model, State
from pliant.solvers.implicit_euler import ImplicitEuler
from pliant.solvers.system import LinearisedSystem


class ForceControl:
    """Apply actuator forces lambda_a as they are (the control of the DDP, u = lambda_a).

    The step keeps the effector rows, so that its condensed problem holds W_ea."""

    roles = ("actuator", "effector")

    def __init__(self, forces: np.ndarray) -> None:
        self.forces = np.asarray(forces, dtype=float)

    def prepare(self, model: Model) -> None:
        pass

    def actuation(self, problem: CondensedProblem, model: Model, state: State) -> np.ndarray:
        return self.forces


@dataclass
class Rollout:
    """A full-FEM trajectory and what the backward pass needs from each of its steps.

    Attributes:
        xs: (N + 1, 2 m) effector states X_k = [p_k; p_dot_k].
        us: (N, n_a) actuator forces applied.
        w_ea: (N, m, n_a) W_ea of each step (Pliant's, with h^2).
        free_motion: (N, m) H_e dv_free of each step (the free velocity change).
        states: the FEM states the steps start from, and the last one (N + 1).
        mass_response: (N, m, m) P = H_e A^-1 M L of each step (with the non-linear part).
    """

    xs: np.ndarray
    us: np.ndarray
    w_ea: np.ndarray
    free_motion: np.ndarray
    states: list[State]
    mass_response: np.ndarray | None = None


class CondensedDynamics:
    """The FEM model seen through its effector rows: full rollouts and condensed derivatives.

    Args:
        model: a robot whose effectors are :class:`PositionEffector` s (their rows, with their
            axes, are the condensed state's positions).
        dt: time step h.
        tangent: the implicit Euler factorisation policy ("fresh": the derivatives are those
            of the step as taken; "lagged": faster on big meshes).
        nonlinear: also save what the non-linear part of Eq. 5.27 needs (one or two more
            solves per step).
        lift: how the non-linear part lifts the effector state onto the nodes,
            "pseudo-inverse" (the thesis'), "compliance" or "static" (see the module's
            docstring).
    """

    def __init__(
        self,
        model: Model,
        dt: float = 0.01,
        *,
        tangent: str = "fresh",
        nonlinear: bool = False,
        lift: str = "pseudo-inverse",
    ) -> None:
        if lift not in ("pseudo-inverse", "compliance", "static"):
            raise ModelError(
                f"lift must be 'pseudo-inverse', 'compliance' or 'static', got {lift!r}"
            )
        self.lift = lift
        if not model.actuators:
            raise ModelError(f"{model.name} has no actuators to optimise")
        if not model.effectors:
            raise ModelError(f"{model.name} has no effectors: the condensed state is theirs")
        for e in model.effectors:
            if not isinstance(e, PositionEffector):
                raise ModelError(
                    f"{e.name}: the condensed dynamics take position effectors, got"
                    f" {type(e).__name__}"
                )
        self.model = model
        self.sim = ImplicitEuler(model, dt, tangent=tangent)
        self.dt = self.sim.dt
        self.nonlinear = nonlinear
        # Effector rows p = weight * H_e x on the selected axes: W's rows / weight are p's.
        self._row_scale = np.concatenate(
            [np.full(e.n_rows, 1.0 / e.weight) for e in model.effectors]
        )
        self.n_positions = int(self._row_scale.size)
        self.n_state = 2 * self.n_positions
        self.n_controls = model.n_actuators

    def effector_state(self, state: State) -> np.ndarray:
        """X = [p; p_dot] of the effector rows at a FEM state."""
        p, v = [], []
        for e in self.model.effectors:
            p.append(e.position(state.positions)[:, e.axes].reshape(-1))
            v.append(e.points.positions(state.velocities)[:, e.axes].reshape(-1))
        return np.concatenate(p + v)

    def step(self, state: State, u: np.ndarray) -> tuple[State, np.ndarray, np.ndarray]:
        """One FEM step under forces u: the next state, W_ea and H_e dv_free of the step."""
        new = self.sim.step(state, ForceControl(u))
        problem = self.sim.last_report.problem
        scale = self._row_scale
        w_ea = scale[:, None] * problem.block("effector", "actuator")
        # delta_free = delta(q) + h H (v + dv_free): its effector rows give H_e dv_free.
        velocity = self.effector_state(state)[self.n_positions :]
        moved = scale * problem.free("effector") - self._effector_rows(state.positions)
        return new, w_ea, moved / self.dt - velocity

    def _effector_rows(self, positions: np.ndarray) -> np.ndarray:
        """delta_e / weight: p - goal on the rows."""
        return np.concatenate(
            [(e.position(positions) - e.goals)[:, e.axes].reshape(-1) for e in self.model.effectors]
        )

    def rollout(
        self,
        start: State,
        us: np.ndarray,
        *,
        policy=None,
    ) -> Rollout:
        """Simulate the full FEM from `start` under the forces `us` (N, n_a).

        `policy(k, x_k, u_k) -> u` may change each control from the state reached (the DDP's
        feedback and bounds); the forces actually applied are returned in the rollout.
        Raises DivergenceError (cause "rollout") naming the node where the FEM diverged."""
        us = np.array(us, dtype=float)
        n = us.shape[0]
        m, na = self.n_positions, self.n_controls
        xs = np.zeros((n + 1, 2 * m))
        w_ea = np.zeros((n, m, na))
        free = np.zeros((n, m))
        mass = np.zeros((n, m, m)) if self.nonlinear else None
        states = [start]
        state = start
        xs[0] = self.effector_state(start)
        static = self._static_shape(start) if mass is not None and self.lift == "static" else None
        for k in range(n):
            if policy is not None:
                us[k] = policy(k, xs[k], us[k])
            try:
                new, w_ea[k], free[k] = self.step(state, us[k])
            except DivergenceError as exc:
                raise DivergenceError(
                    f"the rollout diverged at node {k} of {n}: {exc}", step=k, cause="rollout"
                ) from exc
            if mass is not None:
                mass[k] = self._mass_response(state, static)
            state = new
            states.append(state)
            xs[k + 1] = self.effector_state(state)
            if not np.all(np.isfinite(xs[k + 1])):
                raise DivergenceError(
                    f"the rollout diverged at node {k} of {n}: non-finite effector state",
                    step=k,
                    cause="rollout",
                )
        return Rollout(xs, us, w_ea, free, states, mass)

    def _effector_rows_t(self, state: State) -> np.ndarray:
        """H_e^T of the effector rows (unweighted), on the free DoFs."""
        model = self.model
        space = model.constraint_space(state.positions, model.effectors, with_distance=False)
        return space.jacobian_t * self._row_scale[None, :]

    def _static_shape(self, state: State) -> np.ndarray:
        """K^-1 H_e^T at `state` (its own factorisation of the stiffness)."""
        body = self.model.body
        system = LinearisedSystem(body, policy="fresh")
        system.prepare(body.linearise(state.positions, state.velocities), 0.0, 1.0)
        return system.solve(self._effector_rows_t(state))

    def _mass_response(self, state: State, static: np.ndarray | None) -> np.ndarray:
        """P = H_e A^-1 M L with the factorisation of the step just taken."""
        body = self.model.body
        ht = self._effector_rows_t(state)
        if self.lift == "static":
            shape = static
        elif self.lift == "compliance":
            shape = self.sim.system.solve(ht)
        else:
            shape = ht
        lift = shape @ np.linalg.inv(ht.T @ shape)
        return ht.T @ self.sim.system.solve(body.mass_matvec(lift))

    def derivatives(
        self, rollout: Rollout, *, nonlinear: bool | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Fx (N, 2m, 2m) and Fu (N, 2m, n_a) of Eq. 5.27 and 5.26 along a rollout."""
        nonlinear = self.nonlinear if nonlinear is None else nonlinear
        h, m = self.dt, self.n_positions
        n = rollout.us.shape[0]
        eye = np.eye(m)
        fu = np.concatenate([rollout.w_ea, rollout.w_ea / h], axis=1)
        fx = np.zeros((n, 2 * m, 2 * m))
        if not nonlinear:
            fx[:] = np.block([[eye, h * eye], [np.zeros((m, m)), eye]])
            return fx, fu
        if rollout.mass_response is None:
            raise ModelError(
                "the non-linear part of the state derivative needs a rollout made with"
                " CondensedDynamics(..., nonlinear=True)"
            )
        body = self.model.body
        alpha, beta = body.uniform_rayleigh("trajopt's state derivative (CondensedDynamics)")
        a_m, a_k = 1.0 + h * alpha, h * beta + h * h
        p = rollout.mass_response
        s = (eye - a_m * p) / a_k
        fx[:, :m, :m] = eye - h * h * s
        fx[:, :m, m:] = h * p
        fx[:, m:, :m] = -h * s
        fx[:, m:, m:] = p
        return fx, fu
