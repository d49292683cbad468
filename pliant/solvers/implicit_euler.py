"""Linearised implicit Euler with constraints in the compliance space (Eq. 2.2-2.5).

Per step, with h the time step, K_s = -df/dx and D = alpha M + beta K_s:

    A dv = b + h H^T lambda,   A = (1 + h alpha) M + (h beta + h^2) K_s,
    b = h (f(q) + f_ext) - h alpha M v - (h beta + h^2) K_s v,

solved in two steps: free motion A dv_free = b, then correction dv = dv_free + h A^-1 H^T lambda.
The displacement over the step is h (v + dv), so in the constraint space
delta = W lambda + delta_free with W = h^2 H A^-1 H^T and delta_free = delta(q) + h H (v + dv_free),
all linearised at the start of the step (delta itself is re-evaluated exactly every step).
One factorisation (or one preconditioned block CG) serves the free motion and every constraint
column.
"""

from __future__ import annotations

import numpy as np

from pliant.constraints.condensed import CondensedProblem
from pliant.constraints.control import as_control, constraint_forces
from pliant.constraints.friction import ContactReport, ContactSolution
from pliant.errors import DivergenceError, SolverError
from pliant.model import Model, State
from pliant.solvers.base import StepReport, check_linearisation, check_motion
from pliant.solvers.system import LinearisedSystem, TangentPolicy


class ImplicitEuler:
    """Dynamic solver.

    Args:
        model: the robot.
        dt: time step h.
        tangent: factorisation policy, see :mod:`pliant.solvers.system`.
        rtol: relative tolerance of the preconditioned CG ("pcg" policy).
    """

    def __init__(
        self,
        model: Model,
        dt: float = 0.01,
        *,
        tangent: TangentPolicy = "lagged",
        rtol: float = 1e-10,
    ) -> None:
        if not (np.isfinite(dt) and dt > 0):
            raise SolverError(f"the time step must be finite and > 0, got {dt!r}")
        self.model = model
        self.dt = float(dt)
        self.system = LinearisedSystem(model.body, policy=tangent, rtol=rtol)
        body = model.body
        self._size = float(np.linalg.norm(np.ptp(body.rest_positions, axis=0)))
        self._gravity = body.gravity_forces()
        self.last_report = StepReport()

    def _coefficients(self) -> tuple[float, float]:
        b, h = self.model.body, self.dt
        return 1.0 + h * b.rayleigh_mass, h * b.rayleigh_stiffness + h * h

    def step(self, state: State, control=None) -> State:
        """Advance one step; `control`: None, actuator commands, DirectControl or InverseControl."""
        model, body, h = self.model, self.model.body, self.dt
        ctrl = as_control(control)
        ctrl.prepare(model)
        step = state.step + 1
        lin = body.linearise(state.positions, state.velocities)
        check_linearisation(lin, step, h)
        a_m, a_k = self._coefficients()
        contact = model.contacts.constraint(state.positions, h) if model.contacts else None
        try:
            self.system.prepare(lin, a_m, a_k)
            space = model.constraint_space(
                state.positions,
                roles=getattr(ctrl, "roles", None),
                extra=(contact,) if contact is not None else (),
            )
            v = body.gather(state.velocities)
            rhs = h * body.gather(lin.forces + self._gravity)
            rhs -= a_k * body.gather(lin.stiffness_velocity)
            if a_m != 1.0:
                rhs -= (a_m - 1.0) * body.mass_matvec(v)
            cols = self.system.solve(np.column_stack([rhs, space.jacobian_t]))
        except SolverError as exc:
            raise DivergenceError(f"step {step}: {exc}", step=step, cause="solver") from exc
        dv_free, a_inv_ht = cols[:, 0], cols[:, 1:]
        # delta_free linearised at q with the same H as W, so that a constraint met at rest stays
        # met exactly (evaluating delta at q_free instead leaves an O(h^2) steady-state bias).
        delta_free = space.distance + h * (space.jacobian_t.T @ (v + dv_free))
        w = h * h * (space.jacobian_t.T @ a_inv_ht)
        problem = CondensedProblem(0.5 * (w + w.T), delta_free, space.slices)
        lam, contact_report, contact_forces = constraint_forces(
            ctrl, problem, model, state, contact
        )
        v_new = v + dv_free + h * (a_inv_ht @ lam)
        dq = body.scatter(h * v_new)
        positions = state.positions + dq
        lam_a = lam[space.slices["actuator"]]
        new = State(
            positions,
            body.scatter(v_new),
            state.time + h,
            step,
            lam_a,
            model.actuator_distances(positions),
            contact_forces,
        )
        check_motion(new.positions, new.velocities, dq, self._size, step, h)
        if model.contacts is not None:
            model.contacts.check_travel(dq, step)
        self.last_report = StepReport(
            problem,
            lam_a,
            self.system.last_iterations,
            self.system.factorisations,
            contact=contact_report,
        )
        return new

    def condense(self, state: State) -> CondensedProblem:
        """Exact W and delta_free of the next step from `state` (fresh factorisation)."""
        saved = self.system.policy
        self.system.policy = "fresh"
        try:
            self.step(state.copy(), _Passive())
        finally:
            self.system.policy = saved
        return self.last_report.problem


class _Passive:
    """Control applying no actuation (to read the condensed problem of a step)."""

    def prepare(self, model) -> None:
        pass

    def actuation(self, problem, model, state):
        return np.zeros(problem.n_actuators)

    def actuation_with_contacts(self, problem, model, state, contact) -> ContactSolution:
        return ContactSolution(
            np.zeros(problem.free_distance.size),
            problem.free_distance.copy(),
            ContactReport(),
            problem.slices,
        )
