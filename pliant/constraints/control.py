"""Controls: how actuator forces are chosen once the step is condensed."""

from __future__ import annotations

import math
import numbers
import warnings
from dataclasses import dataclass

import numpy as np

from pliant.constraints.base import change_reference
from pliant.constraints.condensed import CondensedProblem
from pliant.constraints.direct import solve_direct
from pliant.constraints.friction import (
    ContactConstraint,
    ContactForces,
    ContactReport,
    ContactSolution,
    solve_contact,
)
from pliant.constraints.inverse import solve_inverse, solve_inverse_with_contacts
from pliant.errors import (
    ContactConvergenceWarning,
    InfeasibleProblemError,
    ModelError,
    SolverError,
)


@dataclass
class DirectControl:
    """Apply the actuators' commands (in their own modes); None keeps the current commands."""

    values: np.ndarray | None = None
    # Effectors are passive under direct control: the step needs no effector rows.
    roles = ("actuator",)
    # Its contact solution solves a complementarity problem: a contact left out of it at zero
    # force whose gap stays open is part of the whole problem's solution (contact screening).
    complementarity = True
    # The commands are the user's, not answers to the state: a step they make diverge is an
    # error to report, not a feedback answer to fall back from (StaticSolver).
    feedback = False

    def prepare(self, model) -> None:
        if self.values is not None:
            model.set_actuation(self.values)

    def actuation(self, problem: CondensedProblem, model, state) -> np.ndarray:
        """Actuator forces for this step; `state` is the state the step starts from."""
        return solve_direct(
            problem,
            model.actuators,
            change_reference(model.actuators, state),
            previous_actuation=state.actuation,
        )

    def actuation_with_contacts(
        self, problem: CondensedProblem, model, state, contact: ContactConstraint
    ) -> ContactSolution:
        """Actuator and contact forces together (Signorini-Coulomb, Gauss-Seidel), warm-started
        from the previous step's forces."""
        initial = np.zeros(problem.free_distance.size)
        sa, sc = problem.slices["actuator"], problem.slices["contact"]
        if state.actuation.size == sa.stop - sa.start:
            initial[sa] = state.actuation
        initial[sc] = state.contact_forces.warm_start(contact.contacts)
        return solve_contact(
            problem,
            contact.friction,
            actuators=model.actuators,
            previous_displacement=change_reference(model.actuators, state),
            initial=initial,
            tolerance=model.contacts.tolerance,
            max_iterations=model.contacts.max_iterations,
        )


@dataclass
class InverseControl:
    """Choose actuator forces by the QP of Eq. 2.15 so that the effectors reach `goals`.

    goals: one (k, 3) array per effector of the model (a single array for a single effector),
    or None to keep the effectors' current goals. course="soft" widens course bounds that the
    dynamics made infeasible (with a warning) instead of stopping the loop; "hard" raises.
    seed_gap: with contacts, contacts whose gap is at most this distance start the QPCC's
    active set closed (with the ones that carried a force at the previous step), so that the
    QP may choose to close them; the rounds then open those it does not push on.
    contact_time_limit: seconds the QPCC's rounds may take per step (None: no limit); past
    it, the last feasible round's forces are applied with a ContactConvergenceWarning.
    prior, prior_weight: the actuators' displacements to stay near where the effectors do not
    decide between actuations, and the (relative) weight of that pull
    (:func:`pliant.constraints.inverse.prior_terms`); the default regularisation alone pulls
    the forces towards zero.
    """

    goals: list[np.ndarray] | np.ndarray | None = None
    regularisation: float = 1e-3
    course: str = "soft"
    seed_gap: float = 0.0
    contact_time_limit: float | None = 10.0
    prior: np.ndarray | None = None
    prior_weight: float = 0.0
    roles = ("actuator", "effector")

    def prepare(self, model) -> None:
        # Checked here, where they enter: a NaN or negative weight would only show later as
        # a QP that does not converge.
        for name in ("seed_gap", "regularisation", "prior_weight"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, numbers.Real):
                raise ModelError(f"{name} must be a real number, got {value!r}")
            if not (math.isfinite(value) and value >= 0.0):
                raise ModelError(f"{name} must be finite and >= 0, got {value!r}")
        limit = self.contact_time_limit
        if limit is not None and (
            isinstance(limit, bool)
            or not isinstance(limit, numbers.Real)
            or not (math.isfinite(limit) and limit > 0)
        ):
            raise ModelError(f"contact_time_limit must be None or finite and > 0, got {limit!r}")
        if self.course not in ("soft", "hard"):
            raise ModelError(f"course must be 'soft' or 'hard', got {self.course!r}")
        if self.prior is not None:
            prior = np.asarray(self.prior)
            if (
                prior.dtype.kind not in "iuf"
                or prior.shape != (len(model.actuators),)
                or not np.all(np.isfinite(prior))
            ):
                raise ModelError(
                    f"the prior needs one finite displacement per actuator"
                    f" ({len(model.actuators)}), got shape {prior.shape}"
                )
        if self.goals is None:
            return
        goals = [self.goals] if isinstance(self.goals, np.ndarray) else list(self.goals)
        if len(goals) != len(model.effectors):
            raise ModelError(
                f"{model.name} has {len(model.effectors)} effectors, got {len(goals)} goals"
            )
        for eff, g in zip(model.effectors, goals, strict=True):
            eff.goals = g

    def actuation_with_contacts(
        self, problem: CondensedProblem, model, state, contact: ContactConstraint
    ) -> ContactSolution:
        """Actuator forces from the QP with complementarity (Eq. 2.15 with contacts), the
        contacts seeded closed where they carried a force at the previous step; then the
        contact forces for those actuator forces from the Signorini-Coulomb solve, as in a
        direct step. The QP's own contact forces are its model of the contacts' response; the
        physics applied is the contact law's, so a QP whose contact states do not settle (or
        find no solution: the actuators then keep the previous step's forces) warns but
        never applies forces that pull on a contact or let it sink."""
        sa, sc = problem.slices["actuator"], problem.slices["contact"]
        previous = state.contact_forces.warm_start(contact.contacts)
        gap = contact.contacts.gap
        touching = gap <= model.contacts.tolerance
        forces = previous.reshape(-1, 3)
        closed = touching & (forces[:, 0] > 0.0) | (gap <= self.seed_gap)
        # Friction states from the previous step's forces: an axis whose force reaches the
        # pyramid slides with it, the others stick.
        pyramid = np.broadcast_to(contact.friction, gap.shape) / np.sqrt(2.0)
        binds = np.abs(forces[:, 1:]) >= (pyramid * forces[:, 0])[:, None] * (1.0 - 1e-6)
        slip = np.where(binds & (forces[:, :1] > 0.0), np.sign(forces[:, 1:]), 0).astype(int)
        try:
            sol = solve_inverse_with_contacts(
                problem,
                model.actuators,
                change_reference(model.actuators, state),
                contact.friction,
                regularisation=self.regularisation,
                initial_active=closed,
                initial_slip=slip,
                time_limit=self.contact_time_limit,
                prior=self.prior,
                prior_weight=self.prior_weight,
            )
            actuation, rounds, settled = sol.forces[sa], sol.rounds, sol.settled
        except InfeasibleProblemError as exc:
            if state.actuation.size != sa.stop - sa.start:
                raise
            actuation, rounds, settled = state.actuation.copy(), 0, False
            warnings.warn(
                f"{exc}; the actuators keep the previous step's forces",
                ContactConvergenceWarning,
                stacklevel=3,
            )
        else:
            if not settled:
                late = (
                    f" (stopped at the time limit, contact_time_limit={self.contact_time_limit:g}"
                    " s)"
                    if sol.timed_out
                    else ""
                )
                warnings.warn(
                    f"the contact states of the inverse problem did not settle in {rounds}"
                    f" rounds{late}; its last round's actuator forces are applied",
                    ContactConvergenceWarning,
                    stacklevel=3,
                )
        w, d = problem.compliance, problem.free_distance
        held = CondensedProblem(
            w[sc, sc],
            d[sc] + w[sc, sa] @ actuation,
            {
                "actuator": slice(0, 0),
                "effector": slice(0, 0),
                "contact": slice(0, sc.stop - sc.start),
            },
        )
        response = solve_contact(
            held,
            contact.friction,
            initial=previous,
            tolerance=model.contacts.tolerance,
            max_iterations=model.contacts.max_iterations,
        )
        forces = np.zeros(d.size)
        forces[sa], forces[sc] = actuation, response.forces
        report = ContactReport(
            response.report.iterations,
            response.report.residual,
            settled and response.report.converged,
        )
        return ContactSolution(forces, w @ forces + d, report, problem.slices)

    def actuation(self, problem: CondensedProblem, model, state) -> np.ndarray:
        sol = solve_inverse(
            problem,
            model.actuators,
            change_reference(model.actuators, state),
            regularisation=self.regularisation,
            course=self.course,
            prior=self.prior,
            prior_weight=self.prior_weight,
        )
        return sol.actuation


def as_control(control):
    """A control object from None (keep the commands), commands, or any object with
    `prepare(model)` and `actuation(problem, model, state)`; an optional `roles` attribute names
    the constraint roles whose rows the control reads (absent or None: every row), an optional
    `begin(model, state)` is called after `prepare` with the state the step starts from (a
    feedback control sets its effectors' goals there), an optional
    `actuation_with_contacts(problem, model, state, contact)` handles steps with contacts, and
    an optional `feedback` (default True) says whether the control answers the state (the
    static solver then falls back to the step's start when the answer diverges) or only
    applies given commands (False: the divergence is raised)."""
    if control is None:
        return DirectControl()
    if hasattr(control, "actuation") and hasattr(control, "prepare"):
        return control
    return DirectControl(commands(control))


def commands(values) -> np.ndarray:
    """Actuator commands as a 1-D float array: ModelError for text, complex numbers, nested
    arrays (a (2, 2) array is not 4 commands) or anything else that is not a vector of reals."""
    try:
        array = np.asarray(values)
    except (ValueError, TypeError) as exc:  # ragged nested sequences
        raise ModelError(f"actuator commands must be a vector of numbers: {exc}") from None
    if array.dtype.kind not in "iuf" or array.ndim > 1:
        raise ModelError(
            "actuator commands must be a number or a vector of real numbers (one per"
            f" actuator), got {type(values).__name__} of dtype {array.dtype} and shape"
            f" {array.shape}"
        )
    return array.astype(float).reshape(-1)


def constraint_forces(
    control, problem: CondensedProblem, model, state, contact: ContactConstraint | None
) -> tuple[np.ndarray, ContactReport | None, ContactForces]:
    """lambda for every row of `problem` (effectors passive), the contact solver's report and
    the contact forces by identity (None and empty without contact rows)."""
    lam = np.zeros(problem.free_distance.size)
    try:
        if contact is None:
            lam[problem.slices["actuator"]] = control.actuation(problem, model, state)
            return lam, None, ContactForces.empty()
        solve = getattr(control, "actuation_with_contacts", None)
        if solve is None:
            raise ModelError(
                f"{type(control).__name__} does not handle contacts, and {model.name} touches"
                " an obstacle at this step; use DirectControl (commands) with contacts"
            )
        solution = solve(problem, model, state, contact)
    except np.linalg.LinAlgError as exc:  # W singular: the step's solvers raise SolverError
        raise SolverError(
            f"the constraint problem is singular ({exc}): the constraints' compliance W has"
            " no inverse (a time step too small for W to register, or redundant constraints)"
        ) from exc
    forces = ContactForces.from_multipliers(contact.contacts, solution.contact_forces)
    return solution.forces, solution.report, forces
