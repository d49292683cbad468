"""Static equilibrium by Newton iterations with constraints (Eq. 5.1).

K_s(q) dq = f_ext + f(q) + H^T lambda, with lambda the *total* constraint forces chosen at every
iteration from the condensed problem delta = W lambda + delta_free, W = H K_s^-1 H^T,
delta_free = delta(q) + H K_s^-1 (f_ext + f(q)). At convergence the residual vanishes and the
constraints hold exactly.

A feedback control (inverse control) chooses lambda again at each iteration from the iterate's
W; for a goal far out of reach its answer can swing between active sets (a cable slack at one
iterate, pulled at the next), or creep, and the iterations do not converge. Once the updates
stop shrinking (STAGNATION_ITERATIONS), the actuators are held where the last iterate put them
(displacement-controlled ones at their displacement, the others at their force: the direct
problem of those commands, bounds held) and Newton converges on that equilibrium. Where the
control's answer diverges (a pull the bounds allow inverts elements), they are held where the
step started. Both are a best effort, reported by `last_report.held` and an
InverseConvergenceWarning, where they used to be a DivergenceError.

Driven nodes (:class:`pliant.fem.rigid.DrivenNodes`) are held where their carrier puts them at
the state's time: the step solves the equilibrium of the free nodes around them. Rigid bodies
have no static equilibrium of their own here (a body resting on contacts is singular without
inertia): models with rigid bodies use the dynamic step.
"""

from __future__ import annotations

import warnings
from collections.abc import Iterator
from contextlib import contextmanager

import numpy as np

from pliant.constraints.condensed import CondensedProblem
from pliant.constraints.control import DirectControl, constraint_forces
from pliant.constraints.friction import ContactConstraint
from pliant.errors import DivergenceError, InverseConvergenceWarning, ModelError, SolverError
from pliant.model import Model, State
from pliant.solvers.base import (
    StepReport,
    begin_control,
    check_linearisation,
    check_motion,
    number_option,
)
from pliant.solvers.system import LinearisedSystem, TangentPolicy

# Newton's updates shrink quadratically; a feedback control whose last iterations have not
# brought the update ten times below the smallest before them is cycling between active sets
# (or creeping to a fixed point at a linear rate above 0.8).
STAGNATION_ITERATIONS = 10


@contextmanager
def _kept_commands(model: Model) -> Iterator[None]:
    """The model's actuator commands as they are now, restored after a step that held them."""
    saved = [a.value for a in model.actuators]
    try:
        yield
    finally:
        model.set_actuation(saved)


def _slip_from(
    problem: CondensedProblem, contact: ContactConstraint, q: np.ndarray, start: np.ndarray
) -> CondensedProblem:
    """`problem` with its contacts' tangential rows measured from `start` rather than from `q`:
    their free distance gains t.(p(q) - p(start)), each point's tangential motion so far."""
    rows = contact.jacobian(q)
    moved = np.einsum("rai,rai->r", rows.values, (q - start)[rows.nodes]).reshape(-1, 3)
    moved[:, 0] = 0.0
    free = problem.free_distance.copy()
    free[problem.slices["contact"]] += moved.ravel()
    return CondensedProblem(problem.compliance, free, problem.slices)


class StaticSolver:
    """Quasi-static solver: each step solves the equilibrium for the current commands.

    Args:
        model: the robot (must be held: fixed nodes, or the stiffness is singular).
        tolerance: convergence when the Newton update is below tolerance times the body size.
        max_iterations: Newton iterations before giving up.
        tangent: factorisation policy, see :mod:`pliant.solvers.system`.
        consistent: Newton on the consistent tangent of the constrained problem: the exact
            material tangent (for the corotational law, with the variation of the rotation)
            plus the cables' geometric stiffness, sum over the cables of lambda d^2 L/dx^2 at
            their current tensions. Newton then converges quadratically; with SOFA's tangent
            (False) it converges linearly, and not at all on strongly pulled slender bodies.
            Where the consistent tangent is not positive definite, an iteration falls back to
            SOFA's material tangent (keeping the cables' term). W = H K^-1 H^T is then the
            compliance of the equilibrium to a change of the constraint forces.
        augmentation: with the consistent tangent, the Newton matrix of each iteration is
            K + sum_i rho_i h_i^T h_i over the displacement-controlled cables' rows h_i held
            at their displacement at the last iterate (tension strictly inside the force
            bounds), with rho_i = augmentation / W_ii at rest (0 turns it off). A held
            cable's row is an equality, so the update is still Newton's on the constrained
            problem (the rows' multipliers are shifted by rho_i times the rows' residual, zero
            at convergence), but the matrix stays positive definite wherever K is on the
            constraints' null space: a Diamond pulled hard by its cables compresses its arms,
            K alone turns indefinite, and the fallback to SOFA's tangent converges linearly
            (80 iterations and more). :meth:`condense` gives the exact W = H K^-1 H^T, without
            the term.
        slip: what a contact's tangential displacement delta_t (Coulomb's slip, which a
            sliding friction force opposes and a sticking contact holds at zero) is measured
            over. "iteration" (the default): over each Newton update, from the iterate the
            contacts are detected at; a sticking point stays where the iterations left it, and
            a sliding one's friction ends along its last updates, so that the equilibrium
            depends on the iterations' path. "solve": over the whole step, from the state it
            starts from, as the dynamic step measures it over its time step: the equilibrium
            is then that of one quasi-static increment (a sticking point held where the step
            started, a sliding one's friction against its slip over the step), a function of
            the start state and the commands only, whose derivative
            :func:`pliant.diff.static.static_gradient` takes for sliding contacts too.
    """

    def __init__(
        self,
        model: Model,
        *,
        tolerance: float = 1e-10,
        max_iterations: int = 100,
        tangent: TangentPolicy = "fresh",
        consistent: bool = True,
        augmentation: float = 10.0,
        slip: str = "iteration",
    ) -> None:
        if not isinstance(model, Model):
            raise ModelError(f"StaticSolver solves a pliant Model, got {type(model).__name__}")
        if model.rigid_bodies:
            raise ModelError(
                f"{model.name} has rigid bodies: the static solver cannot balance them (a body on"
                " contacts is singular without inertia); use ImplicitEuler"
            )
        held_otherwise = getattr(model.body, "loads", None) or getattr(
            model.body, "projections", None
        )
        if np.all(model.body.free_index >= 0) and not held_otherwise:
            raise ModelError(
                f"{model.name}'s body holds no node: its stiffness is singular (rigid motions"
                " cost no energy), so it has no unique static equilibrium; give it fixed nodes"
                " (or driven ones), or use ImplicitEuler"
            )
        free_motions = getattr(model.body, "free_rigid_motions", list)()
        if free_motions:
            raise ModelError(
                f"{model.name}'s body is free to move rigidly: {'; '.join(free_motions)}. Its"
                " stiffness is singular along these motions (constraints do not hold a body"
                " in the static solve), so the equilibrium is not unique; hold them with fixed"
                " nodes or components, or rest-shape springs, or use ImplicitEuler"
            )
        self.model = model
        self.tolerance = number_option(tolerance, "tolerance", above=0.0)
        self.max_iterations = number_option(
            max_iterations, "max_iterations", at_least=1, integer=True
        )
        self._geometric = consistent and model.geometric_pattern() is not None
        self._augmented = self._augmentation_pattern() if consistent else []
        pattern = None
        if self._geometric or self._augmented:
            parts = [model.geometric_pattern()] if self._geometric else []
            parts += [(np.repeat(d, d.size), np.tile(d, d.size)) for _, d in self._augmented]
            pattern = (
                np.concatenate([r for r, _ in parts]),
                np.concatenate([c for _, c in parts]),
            )
        self.system = LinearisedSystem(
            model.body,
            policy=tangent,
            rtol=1e-12,
            extra_pattern=pattern,
            exact_tangent=consistent,
        )
        self.augmentation = number_option(augmentation, "augmentation", at_least=0.0)
        if slip not in ("iteration", "solve"):
            raise ModelError(f"slip must be 'iteration' or 'solve', got {slip!r}")
        self.slip = slip
        self._row_stiffness: np.ndarray | None = None
        self._size = model.body.extent
        self._gravity = model.body.gravity_forces()
        self.dt = None
        self._time = 0.0  # the time of the loads in the step being solved
        self.last_report = StepReport()

    def _augmentation_pattern(self) -> list[tuple[int, np.ndarray]]:
        """(actuator index, free DoFs its row touches) of each actuator that asks for its row to
        be augmented (:meth:`~pliant.constraints.base.Actuator.augmented_nodes`: a held cable)."""
        free = self.model.body.free_index
        found = []
        for i, a in enumerate(self.model.actuators):
            nodes = a.augmented_nodes()
            if nodes is not None:
                dofs = free[3 * nodes[:, None] + np.arange(3)].ravel()
                found.append((i, dofs[dofs >= 0]))
        return found

    def _condense(
        self,
        q: np.ndarray,
        step: int,
        roles: tuple[str, ...] | None = None,
        contact: ContactConstraint | None = None,
        actuation: np.ndarray | None = None,
        *,
        augment: bool = False,
    ):
        model, body = self.model, self.model.body
        lin = body.linearise(q, time=self._time)
        check_linearisation(lin, step, None)
        space = model.constraint_space(
            q, roles=roles, extra=(contact,) if contact is not None else ()
        )
        extra = []
        if self._geometric:
            tension = np.zeros(model.n_actuators) if actuation is None else actuation
            if tension.size != model.n_actuators:
                tension = np.zeros(model.n_actuators)
            extra.append(model.geometric_stiffness(q, tension))
        first = space.slices["actuator"].start
        held = actuation is not None and actuation.size == model.n_actuators
        for k, (i, dofs) in enumerate(self._augmented):
            rho = 0.0
            cable = model.actuators[i]
            # Only rows held at their displacement (force strictly inside its bounds at the
            # last iterate) are equalities; a row at a force bound is not, and augmenting it
            # would turn Newton into a slow fixed-point iteration.
            if (
                augment
                and held
                and self._row_stiffness is not None
                and self.augmentation > 0
                and cable.min_force < actuation[i] < cable.max_force
            ):
                rho = self.augmentation * self._row_stiffness[k]
            h = space.jacobian_t[dofs, first + i] if rho > 0 else np.zeros(dofs.size)
            extra.append(rho * np.outer(h, h).ravel())
        self.system.prepare(lin, 0.0, 1.0, np.concatenate(extra) if extra else None)
        residual = body.gather(lin.forces + self._gravity)
        cols = self.system.solve(np.column_stack([residual, space.jacobian_t]))
        dq_free, k_inv_ht = cols[:, 0], cols[:, 1:]
        w = space.jacobian_t.T @ k_inv_ht
        delta_free = space.distance + space.jacobian_t.T @ dq_free
        return CondensedProblem(0.5 * (w + w.T), delta_free, space.slices), dq_free, k_inv_ht

    def step(self, state: State, control=None) -> State:
        """The equilibrium under `control` from `state`; StateError if `state` is not one of
        this model's (checked before any kernel runs), DivergenceError if the solve fails."""
        model = self.model
        state = model.check_state(state)
        ctrl = begin_control(model, state, control)
        step = state.step + 1
        self._time = state.time
        q = model.drive(state.positions, state.time)
        if self._augmented and self._row_stiffness is None:
            self._row_stiffness = self._rest_row_stiffness()
        # Each iteration chooses the total constraint forces; the previous iterate's warm-start
        # the next (course bounds still refer to the state the step starts from).
        guide = state.copy()
        feedback = getattr(ctrl, "feedback", True)
        with _kept_commands(model):
            try:
                q, it, held, problem, contact_report = self._iterate(
                    q, ctrl, guide, step, feedback, start=q
                )
            except DivergenceError as exc:
                if not feedback:
                    raise
                # The control's answer carried the body where it cannot go (inverted elements
                # under a pull the bounds allow, a QP with no answer): the actuators stay where
                # the step started, the closest configuration known to be valid.
                self._hold(
                    state.displacement,
                    state.actuation,
                    f"{exc}; the actuators are held where the step started (a best effort)",
                )
                guide = state.copy()
                start = model.drive(state.positions, state.time)
                q, it, _, problem, contact_report = self._iterate(
                    start, DirectControl(), guide, step, False, start=start
                )
                held = True
        self.last_report = StepReport(
            problem,
            guide.actuation,
            self.system.last_iterations,
            self.system.factorisations,
            it,
            contact_report,
            held,
        )
        return State(
            q,
            np.zeros_like(q),
            state.time,
            step,
            guide.actuation,
            model.actuator_distances(q),
            guide.contact_forces,
            displacement_before=state.displacement,
            layout=model.layout,
        )

    def _iterate(
        self, q: np.ndarray, ctrl, guide: State, step: int, feedback: bool, *, start: np.ndarray
    ) -> tuple[np.ndarray, int, bool, CondensedProblem, object]:
        """Newton iterations from `q` to the equilibrium: the positions, the iterations,
        whether the actuators were held (a feedback control cycled), the last iteration's
        condensed problem and contact report. `guide` carries the forces from one iteration
        to the next; `start`: the positions the step started from (slip="solve")."""
        model, body = self.model, self.model.body
        updates, held = [], False
        for it in range(1, self.max_iterations + 1):  # noqa: B007 (reported after the loop)
            contact = model.contacts.constraint(q, None) if model.contacts else None
            try:
                problem, dq_free, k_inv_ht = self._condense(
                    q, step, getattr(ctrl, "roles", None), contact, guide.actuation, augment=True
                )
            except SolverError as exc:
                raise DivergenceError(f"step {step}: {exc}", step=step, cause="solver") from exc
            if contact is not None and self.slip == "solve":
                problem = _slip_from(problem, contact, q, start)
            try:
                lam, contact_report, contact_forces = constraint_forces(
                    ctrl, problem, model, guide, contact
                )
            except SolverError as exc:  # a QP that fails is a step that fails, named as such
                raise DivergenceError(f"step {step}: {exc}", step=step, cause="solver") from exc
            lam_a = lam[problem.slices["actuator"]]
            guide.actuation, guide.contact_forces = lam_a, contact_forces
            dq = body.scatter(dq_free + k_inv_ht @ lam)
            if model.contacts is not None:
                # No colliding point may move further than the detection margin in one update:
                # it could pass through an obstacle it has no contact row for.
                travel = np.linalg.norm(model.contacts.points.displacement(q, dq), axis=1).max()
                if travel > model.contacts.margin:
                    dq *= model.contacts.margin / travel
            q = body.advance(q, dq)
            check_motion(q, np.zeros_like(q), dq, self._size, step, None)
            limit = self.tolerance * self._size
            if contact is not None:
                # Updates below the contact solver's tolerance are its own noise.
                limit = max(limit, model.contacts.tolerance)
            update = float(np.max(np.abs(dq)))
            if update <= limit:
                break
            updates.append(update)
            recent, before = updates[-STAGNATION_ITERATIONS:], updates[:-STAGNATION_ITERATIONS]
            if feedback and not held and before and min(recent) > 0.1 * min(before):
                self._hold(
                    model.actuator_distances(q),
                    lam_a,
                    f"step {step}: {type(ctrl).__name__} and the static equilibrium did not"
                    f" converge together in {it} Newton iterations (its answer swings between"
                    " active sets, as for a goal far out of reach); the actuators are held where"
                    " the last iteration put them, bounds kept (a best effort)",
                    stacklevel=4,
                )
                ctrl, held = DirectControl(), True
        else:
            raise DivergenceError(
                f"step {step}: the static solve did not converge in {self.max_iterations} Newton"
                f" iterations (last update {np.max(np.abs(dq)):.3g}); reduce the load or the"
                " actuation per step (load stepping)",
                step=step,
                cause="solver",
            )
        return q, it, held, problem, contact_report

    def _hold(
        self, displacement: np.ndarray, actuation: np.ndarray, why: str, stacklevel: int = 3
    ) -> None:
        """Command each actuator in its own mode: a displacement-controlled one at
        `displacement`, the others at the force `actuation` gives them; warn `why`."""
        model = self.model
        if actuation.size != model.n_actuators:  # a state released from other actuators
            actuation = np.zeros(model.n_actuators)
        model.set_actuation(
            [
                d if a.mode == "displacement" else f
                for a, d, f in zip(model.actuators, displacement, actuation, strict=True)
            ]
        )
        warnings.warn(why, InverseConvergenceWarning, stacklevel=stacklevel + 1)

    def _rest_row_stiffness(self) -> np.ndarray:
        """1 / W_ii of the augmented cables' rows at rest: the scale of rho_i."""
        model = self.model
        q = model.drive(model.body.rest_positions.copy(), 0.0)
        problem, _, _ = self._condense(q, 0, ("actuator",), None, None)
        first = problem.slices["actuator"].start
        diag = np.diag(problem.compliance)
        return np.array([1.0 / diag[first + i] for i, _ in self._augmented])

    def condense(self, state: State) -> CondensedProblem:
        """Exact W = H K^-1 H^T and delta_free at `state` (with the contact rows detected
        there, if the model has obstacles)."""
        model = self.model
        state = model.check_state(state)
        contact = model.contacts.constraint(state.positions, None) if model.contacts else None
        self._time = state.time
        problem, _, _ = self._condense(state.positions, state.step, None, contact, state.actuation)
        return problem
