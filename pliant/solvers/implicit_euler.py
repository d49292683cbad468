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

Driven nodes (held nodes carried by a kinematic body, :class:`pliant.fem.rigid.DrivenNodes`)
move to their prescribed positions p(t + h) over the step, at v_p = (p(t + h) - q_p) / h. The
free rows of the same implicit step then read, with K_fp the coupling of free and driven DoFs
(a diagonal mass has no such coupling),

    A_ff dv_f = h f_f(q) - h alpha M_ff v_f - (h beta + h^2) (K_ff v_f + K_fp v_p) + ...,

so that K_s v is evaluated with the driven nodes at v_p: the free DoFs feel the driven motion
within the step, not one step late. The constraints are evaluated with the driven nodes at
p(t + h), so that delta_free holds their motion too.

Rigid bodies coupled by contact (:class:`pliant.constraints.contact.CoupledContact`) add
h^2 G M_r^-1 G^T to the contact block of W and h G u_free to its delta_free (u_free: their
free twists under gravity); lambda then also gives their twists u = u_free + h M_r^-1 G^T
lambda_c (pliant.fem.rigid).

Rows of points attached to a rigid body (:mod:`pliant.constraints.attachment`) and of
rigid-body effectors depend on the twists too: with G all rows' dependence on the twists,
W gains h^2 G M_r^-1 G^T and delta_free h G u_free. Attachment rows are eliminated (Schur
complement) before the control solves the rest.

First order (``first_order=True``, SOFA's EulerImplicitSolver with firstOrder): the body
moves as M dq/dt = f(q), no inertia carried from one step to the next (SOFA's tutorials use it
for quasi-static pulls). Per step, (M + h K_s) v' = f(q) + f_ext + H^T lambda, written in the
form above with the step's start velocity taken as zero:

    A dv = b + h H^T lambda,   A = h M + h^2 K_s,   b = h (f(q) + f_ext),

so that v' = dv, q' = q + h v' and W = h^2 H A^-1 H^T = h H (M + h K_s)^-1 H^T (a constraint
force acts for the step as a force, not an impulse); Rayleigh damping has no place in it (SOFA
ignores it there too).

A massless body (``mass="none"``, SOFA's body with no mass component) has M = 0 and no
weight: A = (h beta + h^2) K_s and b = h f - (h beta + h^2) K_s v, so that v + dv =
K_s^-1 f / (h + beta) and the step moves it by h / (h + beta) K_s^-1 f, a Newton step towards
its static equilibrium damped by beta (a whole one with beta = 0), as in SOFA. It must be held
against every rigid motion (ModelError otherwise).

Contacts are screened (under commands): of the points within the contact margin, most stay
open, and a contact that stays open needs no force, so the step solves those closed at the
last step or approaching fast enough to close, and takes in the others only where its
solution would close them. The solution is the whole problem's; the compliance columns solved
are those of the few points that touch (the Trunk pushing a cube: 4 of 75 points).

A model of rigid bodies alone (no deformable body, ``Model(None, ...)``) is stepped by the
rigid bodies' scheme (:class:`pliant.solvers.rigid.RigidSolver`: the same free motion, M^-1
and contact solver as the coupled step, with the model's joints, obstacles and contact law);
the state carries no nodes.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import NamedTuple

import numpy as np

from pliant.constraints.attachment import eliminate
from pliant.constraints.base import Constraint
from pliant.constraints.condensed import CondensedProblem
from pliant.constraints.control import constraint_forces
from pliant.constraints.friction import ContactForces, ContactReport, ContactSolution
from pliant.errors import ConstraintError, DivergenceError, ModelError, SolverError
from pliant.fem.body import PARALLEL_MIN_TETS
from pliant.fem.kernels import equal_2d
from pliant.fem.rigid import KinematicBody, RigidStep, integrate_poses
from pliant.model import ConstraintSpace, Model, State
from pliant.solvers.base import (
    StepReport,
    begin_control,
    check_linearisation,
    check_motion,
    number_option,
)
from pliant.solvers.compliance import PointCompliance, PointRows
from pliant.solvers.compliance_kernels import framed_block
from pliant.solvers.rigid import RigidSolver, RigidState, RigidWorld
from pliant.solvers.system import LinearisedSystem, TangentPolicy

#: The slices of a problem without rows (as Model.constraint_space gives them).
_NO_ROWS = {role: slice(0, 0) for role in ("actuator", "effector", "contact")}
MIN_DT = 1e-12  # s: the smallest time step accepted (see ImplicitEuler.__init__)
#: Free DoFs under which a body factorises on the step's own thread: handing a factorisation
#: of a few tens of microseconds to the background thread costs more than it saves (measured
#: with both cores busy: the Trunk proxy, a 30-node rod of 174 DoFs, 23 % faster without; the
#: 8 mm FEM Trunk, 633 DoFs, whose factorisation takes 0.5 ms, 10 % faster with).
BACKGROUND_MIN_DOFS = 300


class ImplicitEuler:
    """Dynamic solver.

    Args:
        model: the robot.
        dt: time step h.
        tangent: factorisation policy, see :mod:`pliant.solvers.system`.
        rtol: relative tolerance of the preconditioned CG ("pcg" policy).
        point_compliance: keep the colliding points' compliance columns for the life of a
            factorisation (:mod:`pliant.solvers.compliance`) rather than solving three columns
            per contact at every step; same results to round-off. Not used by "pcg", whose
            solves are not one factorisation's, nor for points whose rows change with the
            state (a surface skinned on a rod, ``points.linear`` False). With the "lagged"
            tangent and no contact, the same for the points of cables and position effectors
            when they are few (at most 4/3 of a point per row, as the Diamond's one point per
            cable): their rows' columns are then read from the points' (:class:`pliant.
            solvers.compliance.PointRows`).
        contact_screening: with point compliance and a control whose contact solution is a
            complementarity problem's (commands: DirectControl), solve the contacts that may
            close and check that the others stay open (:meth:`_screened`); same solution to
            the contact tolerance, without the columns of the points that stay open.
        screen_gap: when a round of screening would close contacts it left out, the next
            round takes in every contact whose gap that round leaves below this (default: a
            tenth of the contact margin); any value >= 0 gives the same solution, it only
            sets how many rounds are needed.
        first_order: integrate M dq/dt = f(q) (no inertia; SOFA's EulerImplicitSolver with
            ``firstOrder``): see the module docstring. The body's Rayleigh damping is not used.
    """

    def __init__(
        self,
        model: Model,
        dt: float = 0.01,
        *,
        tangent: TangentPolicy = "lagged",
        rtol: float = 1e-10,
        point_compliance: bool = True,
        contact_screening: bool = True,
        screen_gap: float | None = None,
        first_order: bool = False,
    ) -> None:
        if not isinstance(model, Model):
            raise ModelError(f"ImplicitEuler steps a pliant Model, got {type(model).__name__}")
        # Below MIN_DT, h^2 in W underflows next to the mass: the constraint problem is
        # singular (1e-200 s), long before any step of use (SOFA's scenes: 1e-2 to 1e-4 s).
        self.dt = number_option(dt, "the time step dt", at_least=MIN_DT)
        rtol = number_option(rtol, "rtol", above=0.0)
        if screen_gap is not None:
            screen_gap = number_option(screen_gap, "screen_gap", at_least=0.0)
        self.model = model
        self.first_order = bool(first_order)
        self.last_report = StepReport()
        self._rigid_solver = None
        if model.body is None:
            if self.first_order:
                raise ModelError(
                    f"{model.name} has no deformable body: first_order (no inertia) does not"
                    " apply to its rigid bodies, stepped with their inertia"
                )
            self._rigid_solver = _rigid_solver(model, self.dt)
            return
        _check_massless_held(model)
        self.system = LinearisedSystem(model.body, policy=tangent, rtol=rtol)
        self._objects, self._object_rows = self._find_objects()
        # Each attachment with its body's index.
        self._attached = [
            (next(i for i, b in enumerate(model.rigid_bodies) if b is a.body), a)
            for a in model.attachments
        ]
        self._points = (
            PointCompliance(model.contacts.points, model.body.free_index)
            if point_compliance
            and model.contacts is not None
            and model.contacts.points.linear
            and not model.contacts.surfaces  # rows on relative points: columns every step
            and not model.contacts.rigid_surfaces
            else None
        )
        self._row_points: dict[tuple[str, ...] | None, PointRows | None] = {}
        self._rows_on_points = point_compliance and tangent == "lagged"
        self.contact_screening = contact_screening
        margin = model.contacts.margin if model.contacts is not None else 0.0
        self.screen_gap = 0.1 * margin if screen_gap is None else float(screen_gap)
        body = model.body
        # Bodies whose kernels run on one thread leave the other core to a factorisation,
        # unless it is too small to be worth the hand-over.
        self._background = (
            body.n_elements < PARALLEL_MIN_TETS and body.n_free >= BACKGROUND_MIN_DOFS
        )
        self._size = body.extent
        # The kept factorisation may be turned (LinearisedSystem.prepare) where the step solves
        # no constraint columns: compliance columns kept for its life would not be.
        self._warp = not (
            model.actuators or model.effectors or model.attachments or model.contacts is not None
        )
        self._gravity = body.gravity_forces()
        # The linearisation of the last state returned, checked before it was (see `step`);
        # off while `condense` takes its passive step.
        self._ahead: LookAhead | None = None
        self._look_ahead = True
        self._per_body = None  # ((dt, the body's per-DoF damping), (a_m, a_k)): _coefficients

    def _coefficients(self) -> tuple[float, float] | tuple[np.ndarray, np.ndarray]:
        """(a_m, a_k) of A = a_m M + a_k K_s: floats, or one value a free DoF where the body
        joins bodies of different Rayleigh damping (their blocks of M and K_s are disjoint)."""
        b, h = self.model.body, self.dt
        if self.first_order:
            return h, h * h
        per_body = b.rayleigh_dofs()
        if per_body is not None:
            key = None if self._per_body is None else self._per_body[0]
            if key is None or key[0] != h or key[1] is not per_body:
                alpha, beta = per_body  # the same arrays every step: the factorisation is kept
                self._per_body = ((h, per_body), (1.0 + h * alpha, h * beta + h * h))
            return self._per_body[1]
        return 1.0 + h * b.rayleigh_mass, h * b.rayleigh_stiffness + h * h

    def step(self, state: State, control=None) -> State:
        """Advance one step; `control`: None, actuator commands, DirectControl or InverseControl.

        Raises:
            StateError: `state` is not one of this model's (checked before any kernel runs).
            DivergenceError: the step failed or its result is not a usable state.
        """
        model, body, h = self.model, self.model.body, self.dt
        state = model.check_state(state)
        if self._rigid_solver is not None:
            return self._rigid_step_only(state, control)
        ctrl = begin_control(model, state, control)
        step = state.step + 1
        at = model.drive(state.positions, state.time + h) if model.drivers else state.positions
        ahead = self._ahead
        lin, drive = self._linearise(state)
        if ahead is None or lin is not ahead.linearisation:
            check_linearisation(lin, step, h)  # the look-ahead's was, by the step that made it
        a_m, a_k = self._coefficients()
        try:  # on a small body, a refactorisation runs on while the step detects its contacts
            self.system.prepare(lin, a_m, a_k, background=self._background, warp=self._warp)
        except SolverError as exc:
            raise DivergenceError(f"step {step}: {exc}", step=step, cause="solver") from exc
        rigid = self._rigid_step(state)
        contact = model.contacts.constraint(state.positions, h, rigid) if model.contacts else None
        rhs = h * body.gather(lin.forces + self._gravity)
        if self.first_order:  # no velocity carried into the step
            v = np.zeros(body.n_free)
        else:
            v = body.gather(state.velocities)
            rhs -= a_k * body.gather(lin.stiffness_velocity)
            if np.ndim(a_m) or a_m != 1.0:
                rhs -= (a_m - 1.0) * body.mass_matvec(v)
        roles = getattr(ctrl, "roles", None)
        self._place_objects(rigid)
        solved = None  # (lambda, contact report, contact forces) when screening solved them
        try:
            point_rows = (
                self._point_rows(roles) if contact is None and not model.attachments else None
            )
            if contact is not None and self._points is not None and self.system.policy != "pcg":
                free = self._free_with_points(at, roles, rhs)
                if self.contact_screening and getattr(ctrl, "complementarity", False):
                    problem, correction, contact, solved = self._screened(
                        ctrl, state, at, free, contact, v, rigid
                    )
                else:
                    problem, correction = self._with_points(at, free, contact, v, rigid)
            elif point_rows is not None:
                problem, correction = self._condense_on_points(at, roles, rhs, v, point_rows)
            else:
                problem, correction = self._condense(at, roles, contact, rhs, v, rigid)
            # A QP that fails is a step that fails, named as such.
            lam, contact_report, contact_forces = solved or self._forces(
                ctrl, problem, state, contact
            )
        except SolverError as exc:
            raise DivergenceError(f"step {step}: {exc}", step=step, cause="solver") from exc
        dv_free, response, rigid_rows = correction
        v_new = v + dv_free + h * response(lam)
        dq = body.scatter(h * v_new)
        positions = body.advance(state.positions, dq)
        new_velocities = body.scatter(v_new)
        if model.drivers:
            positions = model.drive(positions, state.time + h)
            new_velocities += drive
        lam_a = lam[problem.slices["actuator"]]
        new = State(
            positions,
            new_velocities,
            state.time + h,
            step,
            lam_a,
            model.actuator_distances(positions),
            contact_forces,
            displacement_before=state.displacement,
            layout=model.layout,
        )
        if rigid is not None:
            twists = (
                rigid.twists(rigid_rows, lam, h, step)
                if rigid_rows is not None
                else rigid.twists_free
            )
            new.rigid_positions, new.rigid_rotations = integrate_poses(
                rigid.positions, rigid.rotations, twists, h
            )
            new.rigid_velocities = twists[:, :3].copy()
            new.rigid_angular_velocities = twists[:, 3:].copy()
            self._place_objects(new)
        check_motion(new.positions, new.velocities, dq, self._size, step, h)
        if self._look_ahead:
            # The next step's linearisation, now: a state with inverted elements is refused
            # by the step that made it, never returned (the next step reuses it).
            try:
                ahead, drive = self._linearise(new, reuse=False)
            except (ConstraintError, ModelError):
                # A driver refuses its next pose (a servo told to leave its range): that is
                # the next step's error, raised by it, not this step's.
                self._ahead = None
            else:
                check_linearisation(ahead, step, h)
                self._ahead = LookAhead(
                    new.time,
                    h,
                    new.positions.copy(),
                    new.velocities.copy(),
                    ahead,
                    drive,
                    self.model.body.revision,
                )
        if model.contacts is not None:
            model.contacts.check_travel(positions, dq, step)
        self.last_report = StepReport(
            problem,
            lam_a,
            self.system.last_iterations,
            self.system.factorisations,
            contact=contact_report,
        )
        return new

    def _rigid_step_only(self, state: State, control) -> State:
        """A step of a model without deformable body (module docstring)."""
        if control is not None and np.size(control) != 0:
            raise ModelError(f"{self.model.name} has no actuators; got a control {control!r}")
        solver = self._rigid_solver
        solver.dt = self.dt
        after = solver.step(
            RigidState(
                state.rigid_positions,
                state.rigid_rotations,
                state.rigid_velocities,
                state.rigid_angular_velocities,
                state.time,
                state.step,
                state.contact_forces,
            )
        )
        self.last_report = StepReport(contact=solver.last_report)
        none = np.zeros((0, 3))
        return State(
            none,
            none.copy(),
            after.time,
            after.step,
            np.zeros(0),
            np.zeros(0),
            after.contacts,
            after.positions,
            after.rotations,
            after.velocities,
            after.angular_velocities,
            displacement_before=np.zeros(0),
            layout=self.model.layout,
        )

    def _linearise(self, state: State, *, reuse: bool = True):
        """The body linearised at `state` with the velocities of a step from it (driven nodes
        at their velocity over the step), and those drive velocities (None without drivers).
        With `reuse`, the look-ahead of the last step when `state` holds what it returned, the
        drivers still move as they did then (a cart retargeted since has other drive
        velocities, hence another linearisation) and the body's forces read what they read
        then (its :attr:`~pliant.fem.body.Revised.revision`: a proxy's rest curvature, set
        between steps, is its actuation)."""
        model, body = self.model, self.model.body
        drive = model.drive_velocities(state, self.dt) if model.drivers else None
        ahead = self._ahead
        if (
            reuse
            and ahead is not None
            and (ahead.time, ahead.dt) == (state.time, self.dt)
            and _same(ahead.positions, state.positions)
            and _same(ahead.velocities, state.velocities)
            and (drive is None or np.array_equal(ahead.drive, drive))
            and ahead.revision == body.revision
        ):
            return ahead.linearisation, drive
        velocities = state.velocities
        if drive is not None:
            velocities = body.scatter(body.gather(state.velocities)) + drive
        return body.linearise(state.positions, velocities, time=state.time), drive

    def _condense(self, at, roles, contact, rhs, v, rigid):
        """W and delta_free with every constraint column solved (one factorisation, one block
        solve); returns the problem and (dv_free, lambda -> A^-1 H^T lambda)."""
        h = self.dt
        extra = ((contact,) if contact is not None else ()) + tuple(self.model.attachments)
        if not (extra or rigid is not None or self.model.actuators or self.model.effectors):
            # No row (a bare body): the free motion is the step's motion, with no constraint
            # space to build, nor products of empty blocks.
            dv_free = self.system.solve(rhs)
            n = dv_free.size
            problem = CondensedProblem(np.zeros((0, 0)), np.zeros(0), dict(_NO_ROWS))
            return problem, (dv_free, lambda lam: np.zeros(n), None)
        space = self.model.constraint_space(at, roles=roles, extra=extra)
        cols = self.system.solve(np.column_stack([rhs, space.jacobian_t]))
        dv_free, a_inv_ht = cols[:, 0], cols[:, 1:]
        # delta_free linearised at q with the same H as W, so that a constraint met at rest stays
        # met exactly (evaluating delta at q_free instead leaves an O(h^2) steady-state bias).
        delta_free = space.distance + h * (space.jacobian_t.T @ (v + dv_free))
        w = h * h * (space.jacobian_t.T @ a_inv_ht)
        g = self._couple_rigid(w, delta_free, space.slices, contact, rigid)
        problem = CondensedProblem(0.5 * (w + w.T), delta_free, space.slices)
        return problem, (dv_free, lambda lam: a_inv_ht @ lam, g)

    def _point_rows(self, roles) -> PointRows | None:
        """The rows of `roles` read through their points' columns, or None where that does
        not pay (see PointRows.build) or the rows are not points' (cavities, objects)."""
        if not self._rows_on_points:
            return None
        key = None if roles is None else tuple(roles)
        if key not in self._row_points:
            model = self.model
            wanted = [
                c for c in model.actuators + model.effectors if roles is None or c.role in roles
            ]
            self._row_points[key] = PointRows.build(wanted, model.body.free_index)
        return self._row_points[key]

    def _condense_on_points(self, at, roles, rhs, v, rows: PointRows):
        """As `_condense` without contact, the rows' columns from their points' columns kept
        for the factorisation: one solve (the free motion) per step."""
        h = self.dt
        dv_free = self.system.solve(rhs)
        distance, w, moved, response = rows.condense(
            self.system.solve, self.system.factorisations, at, v + dv_free
        )
        problem = CondensedProblem(0.5 * h * h * (w + w.T), distance + h * moved, rows.slices)
        return problem, (dv_free, response, None)

    def _free_with_points(self, at, roles, rhs) -> _FreeMotion:
        """The free motion and the columns of the actuator, effector and attachment rows (one
        block solve)."""
        model = self.model
        space = model.constraint_space(at, roles=roles)
        attached = model.constraint_space(at, model.attachments) if model.attachments else None
        blocks = [rhs, space.jacobian_t] + ([attached.jacobian_t] if attached else [])
        cols = self.system.solve(np.column_stack(blocks))
        n_s = space.distance.size
        return _FreeMotion(space, cols[:, 0], cols[:, 1 : 1 + n_s], attached, cols[:, 1 + n_s :])

    def _screened(self, ctrl, state, at, free: _FreeMotion, contact, v, rigid):
        """The step's problem and solution with only the contacts that may close: first those
        closed at the last step and those the current velocities would close over the step;
        then, while the solution would close another (its gap after the step, read from the
        velocities the solution gives, below minus the contact tolerance), the solve again
        with every contact whose gap it leaves below `screen_gap`.

        A contact left out has zero force and a gap that stays open, so it meets Signorini's
        and Coulomb's laws as it is: the solution of the reduced problem is a solution of the
        whole one, to the contact tolerance. It needs no compliance columns: a push moving a
        few of the points within the margin solves the columns of those few."""
        h, cache, model = self.dt, self._points, self.model
        coupled = contact.rigid_jacobian is not None
        rows = contact.rows
        index, frames = rows.contacts.index_a, rows.frames
        k = index.size
        distance = rows.distance(at)[0::3]
        normal_twist = contact.rigid_jacobian[0 : 3 * k : 3] if coupled else None

        def gaps(velocities: np.ndarray, twists: np.ndarray | None) -> np.ndarray:
            moved = np.einsum("kj,kj->k", frames[:, 0], cache.read(index, velocities))
            gap = distance + h * moved
            if coupled:
                gap += h * (normal_twist @ twists.reshape(-1))
            return gap

        # First the contacts closed at the last step or that their velocities would close
        # over this one; then those the solution would close.
        current = np.hstack([state.rigid_velocities, state.rigid_angular_velocities])
        wanted = (state.contact_forces.warm_start(rows.contacts)[0::3] != 0.0) | (
            gaps(v, current if coupled else None) < 0.0
        )
        tolerance, rounds, sweeps, newton = model.contacts.tolerance, 0, 0, 0
        while True:
            rounds += 1
            kept = np.flatnonzero(wanted)
            part = contact.take(kept)
            problem, correction = self._with_points(at, free, part, v, rigid)
            lam, report, _ = self._forces(ctrl, problem, state, part)
            sweeps += report.iterations
            newton += report.newton_steps
            dv_free, response, rigid_rows = correction
            lam_c = lam[problem.slices["contact"]]
            twists = (
                rigid.twists(rigid_rows, lam, h, state.step + 1) if rigid_rows is not None else None
            )
            after = gaps(v + dv_free + h * response(lam), twists)
            if not np.any(~wanted & (after < -tolerance)):
                break
            wanted |= after < self.screen_gap
        # Every contact's multipliers, zero for those left out.
        full = np.zeros((len(contact.contacts), 3))
        full[kept] = lam_c[: 3 * kept.size].reshape(-1, 3)
        full[k:] = lam_c[3 * kept.size :].reshape(-1, 3)
        forces = ContactForces.from_multipliers(contact.contacts, full)
        report = replace(
            report, iterations=sweeps, newton_steps=newton, screened=k - kept.size, rounds=rounds
        )
        return problem, correction, part, (lam, report, forces)

    def _with_points(self, at, free: _FreeMotion, contact, v, rigid):
        """As `_condense`, with the contact columns read from the colliding points' compliance
        kept for the factorisation (:mod:`pliant.solvers.compliance`): only the actuator and
        effector columns are solved at every step (in `free`)."""
        h, cache = self.dt, self._points
        space, dv_free, a_inv_ht = free.space, free.dv_free, free.a_inv_ht
        rows = contact.rows
        index, frames = rows.contacts.index_a, rows.frames
        k, n_s, n_c = index.size, space.distance.size, contact.n_rows
        n_b = 0 if free.attached is None else free.attached.distance.size
        slots = cache.columns(self.system.solve, self.system.factorisations, index)
        # Contact rows' products, all through P (the points' displacement rows).
        w_cc = framed_block(frames, cache.block(index, slots))
        w_ca = cache.framed_rows(index, frames, a_inv_ht)
        moved = cache.framed_rows(index, frames, (v + dv_free)[:, None]).reshape(-1)
        n = n_s + n_c + n_b
        w = np.zeros((n, n))
        w[:n_s, :n_s] = space.jacobian_t.T @ a_inv_ht
        w[n_s : n_s + 3 * k, :n_s] = w_ca
        w[:n_s, n_s : n_s + 3 * k] = w_ca.T
        w[n_s : n_s + 3 * k, n_s : n_s + 3 * k] = w_cc
        delta_free = np.zeros(n)
        delta_free[:n_s] = space.distance + h * (space.jacobian_t.T @ (v + dv_free))
        delta_free[n_s : n_s + n_c] = contact.distance(at)
        delta_free[n_s : n_s + 3 * k] += h * moved
        if n_b:  # attachment rows, last: their columns were solved with the free motion
            attached, a_inv_hb = free.attached, free.a_inv_hb
            b = slice(n_s + n_c, n)
            w[b, :n_s] = attached.jacobian_t.T @ a_inv_ht
            w[:n_s, b] = w[b, :n_s].T
            w[n_s : n_s + 3 * k, b] = cache.framed_rows(index, frames, a_inv_hb)
            w[b, n_s : n_s + 3 * k] = w[n_s : n_s + 3 * k, b].T
            w[b, b] = attached.jacobian_t.T @ a_inv_hb
            delta_free[b] = attached.distance + h * (attached.jacobian_t.T @ (v + dv_free))
        w *= h * h
        end = slice(n_s + n_c, n_s + n_c)  # where constraint_space puts an absent role
        slices = {r: sl if sl.stop > sl.start else end for r, sl in space.slices.items()}
        slices["contact"] = slice(n_s, n_s + n_c)
        if n_b:
            slices["attachment"] = slice(n_s + n_c, n)
        g = self._couple_rigid(w, delta_free, slices, contact, rigid)
        problem = CondensedProblem(0.5 * (w + w.T), delta_free, slices)

        def response(lam: np.ndarray) -> np.ndarray:
            forces = np.einsum("irs,ir->is", frames, lam[n_s : n_s + 3 * k].reshape(k, 3))
            out = a_inv_ht @ lam[:n_s] + cache.apply(slots, forces)
            if n_b:
                out += free.a_inv_hb @ lam[n_s + n_c :]
            return out

        return problem, (dv_free, response, g)

    def _forces(self, ctrl, problem: CondensedProblem, state: State, contact):
        """lambda for every row of `problem`, the contact report and forces: the control
        solves the problem with its attachment rows eliminated, then their multipliers follow
        (:func:`pliant.constraints.attachment.eliminate`)."""
        elimination = eliminate(problem)
        if elimination is None:
            return constraint_forces(ctrl, problem, self.model, state, contact)
        lam, report, forces = constraint_forces(
            ctrl, elimination.problem, self.model, state, contact
        )
        return elimination.full(lam), report, forces

    def _couple_rigid(self, w, delta_free, slices, contact, rigid) -> np.ndarray | None:
        """Add the rigid bodies' share to a problem: with G the rows' dependence on the bodies'
        twists (contact rows on bodies, rigid-body effectors, attachments; zero elsewhere),
        W += h^2 G M^-1 G^T and delta_free += h G u_free. Returns G (None without bodies)."""
        if rigid is None:
            return None
        h, model = self.dt, self.model
        n = len(model.rigid_bodies)
        g = np.zeros((delta_free.size, 6 * n))
        if contact is not None and contact.rigid_jacobian is not None:
            g[slices["contact"]] = contact.rigid_jacobian
        se = slices["effector"]
        if self._object_rows is not None and se.stop > se.start:
            g[se] = self._object_rows
        if model.attachments:
            g[slices["attachment"]] = np.vstack([a.twist_rows(i, n) for i, a in self._attached])
        w += h * h * (g @ rigid.inverse_mass @ g.T)
        delta_free += h * (g @ rigid.twists_free.reshape(-1))
        return g

    def _find_objects(self) -> tuple[list[tuple[int, Constraint]], np.ndarray | None]:
        """The rigid-body effectors, each with its body's index, and their rows' dependence on
        the twists over all effector rows (None without such effectors)."""
        model, found, row = self.model, [], 0
        n_bodies = len(model.rigid_bodies)
        rows = np.zeros((sum(e.n_rows for e in model.effectors), 6 * n_bodies))
        for effector in model.effectors:
            if effector.rigid_body is not None:
                index = next(
                    (i for i, b in enumerate(model.rigid_bodies) if b is effector.rigid_body),
                    None,
                )
                if index is None:
                    raise ModelError(f"{effector.name}: its rigid body is not one of the model's")
                rows[row : row + effector.n_rows] = effector.twist_rows(index, n_bodies)
                found.append((index, effector))
            row += effector.n_rows
        return found, (rows if found else None)

    def _place_objects(self, rigid) -> None:
        """Give the rigid-body effectors their body's centre and the attachments their body's
        pose (`rigid`: a RigidStep or State)."""
        if rigid is None:
            return
        centres = getattr(rigid, "rigid_positions", None)
        centres = rigid.positions if centres is None else centres
        rotations = getattr(rigid, "rigid_rotations", None)
        rotations = rigid.rotations if rotations is None else rotations
        for index, effector in self._objects:
            effector.centre = centres[index].copy()
        for index, attachment in self._attached:
            attachment.set_pose(centres[index].copy(), rotations[index].copy())

    def _rigid_step(self, state: State) -> RigidStep | None:
        """The rigid bodies' free motion over the step (None without rigid bodies)."""
        model = self.model
        if not model.rigid_bodies:
            return None
        return RigidStep.free(
            model.rigid_bodies,
            state.rigid_positions,
            state.rigid_rotations,
            state.rigid_velocities,
            state.rigid_angular_velocities,
            model.body.gravity,
            self.dt,
        )

    def condense(self, state: State) -> CondensedProblem:
        """Exact W and delta_free of the next step from `state` (fresh factorisation)."""
        state = self.model.check_state(state)
        saved = self.system.policy
        self.system.policy, self._look_ahead = "fresh", False
        try:
            self.step(state.copy(), _Passive())
        finally:
            self.system.policy, self._look_ahead = saved, True
        return self.last_report.problem


def _rigid_solver(model: Model, dt: float) -> RigidSolver:
    """The rigid bodies' solver of a model without deformable body: its bodies, joints, moving
    obstacles and the other shapes of its contacts (still, each with its friction), its
    gravity, and its contacts' margin and tolerance."""
    contacts = model.contacts
    moving = {id(o.shape) for o in model.obstacles}
    still = []
    if contacts is not None:
        if contacts.planes is not None or contacts.surfaces or contacts.points is not None:
            raise ModelError(
                f"{model.name}: contact points, point planes and surface contacts are a"
                " deformable body's; a model without one collides its rigid bodies with shapes"
            )
        still = [
            KinematicBody(shape, friction=float(mu), name=f"shape {i}")
            for i, (shape, mu) in enumerate(
                zip(
                    contacts.shapes,
                    np.broadcast_to(contacts.friction, len(contacts.shapes)),
                    strict=True,
                )
            )
            if id(shape) not in moving
        ]
    world = RigidWorld(
        model.rigid_bodies, [*still, *model.obstacles], gravity=model.gravity, joints=model.joints
    )
    if contacts is None:
        return RigidSolver(world, dt)
    return RigidSolver(
        world,
        dt,
        margin=contacts.margin or 0.0,
        tolerance=contacts.tolerance,
        max_iterations=contacts.max_iterations,
    )


def _check_massless_held(model: Model) -> None:
    """ModelError where the body has no mass and something leaves it free to move rigidly:
    its step matrix is then (h beta + h^2) K_s alone, singular along those motions."""
    body = model.body
    if not getattr(body, "massless", False):
        return
    free = body.free_rigid_motions()
    if free:
        raise ModelError(
            f"{model.name}'s body has no mass and is free to move rigidly: {'; '.join(free)}."
            " Without mass its implicit step matrix is the stiffness alone, singular along"
            " these motions; hold them (fixed nodes or components, rest-shape springs) or"
            " give the body a mass"
        )


class LookAhead(NamedTuple):
    """The next step's linearisation, computed at the end of a step from the state it
    returned, and what it was computed with: reused only by a step from that state, time
    step, drive and body revision."""

    time: float
    dt: float
    positions: np.ndarray
    velocities: np.ndarray
    linearisation: object
    drive: np.ndarray | None
    revision: int


@dataclass(frozen=True)
class _FreeMotion:
    """A step's free motion and the columns A^-1 H^T of its actuator and effector rows (and
    of its attachment rows)."""

    space: ConstraintSpace
    dv_free: np.ndarray
    a_inv_ht: np.ndarray
    attached: ConstraintSpace | None = None  # the attachment rows, when the model has some
    a_inv_hb: np.ndarray | None = None


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


def _same(kept: np.ndarray, given: np.ndarray) -> bool:
    """np.array_equal for the look-ahead's arrays (n, 3) and a state's, in one compiled pass."""
    if kept.shape != given.shape or given.ndim != 2:
        return np.array_equal(kept, given)
    return equal_2d(kept, given)
