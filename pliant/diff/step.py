"""Adjoint of one linearised implicit Euler step (:class:`pliant.solvers.ImplicitEuler`).

The step from (q, v), free DoFs only, with a_m = 1 + h alpha, a_k = h beta + h^2 and
A = a_m M + a_k K_s(q) (K_s the assembled tangent, refactorised every step: the "fresh"
policy), is (:mod:`pliant.solvers.implicit_euler`)

    A (v' - v) = b + h H^T lambda,   b = h (f(q) + g + f_ext) - a_k K_s(q) v - (a_m - 1) M v,
    q' = q + h v',

with lambda the actuators' forces chosen by the direct problem. At the forward solution each
actuator row is one of

* an *equality* row d: a displacement command met (force strictly inside its bounds), or a
  force command held at a course bound: delta_d(q) + h H_d v' = t_d, lambda_d unknown
  (this is delta_free + W lambda = t with W = h^2 H A^-1 H^T, delta_free = delta(q) +
  h H (v + A^-1 b));
* a *force* row f: lambda_f known (a force command inside its bounds, or a displacement
  command whose force sits at a bound: held fixed there).

So the step solves F(y, x) = 0 for y = (v', lambda_d), with

    F1 = A (v' - v) - b - h H^T lambda,      F2 = h H_d v' + delta_d(q) - t_d,

and dF/dy = [[A, -h H_d^T], [h H_d, 0]]. For a loss L(q', v'), with
vbar = dL/dv' + h dL/dq', the adjoint mu = (mu_v, mu_l) solves dF/dy^T mu = (vbar, 0):

    W_dd mu_l = h H_d A^-1 vbar,    mu_v = A^-1 (vbar - h H_d^T mu_l)

(the step's own factorisation and W), and every input x gets xbar = -(dF/dx)^T mu:

* v:  dF1/dv = -A + a_k K_s + (a_m - 1) M = -M, so vbar_in = M mu_v.
* q:  qbar_in = dL/dq' - grad_q [a_k mu_v.K_s(q) v' - h mu_v.f(q) - h lambda.H(q) mu_v
  + h mu_l.H_d(q) v' + mu_l.delta_d(q)]. The element part is differentiated in reverse
  mode per element for the corotational laws (:mod:`pliant.diff.kernels`), by complex step
  on each element's 12 coordinates for the others (:mod:`pliant.diff.elements`), exact to
  round-off either way;
  grad_q (c.H(q) w) = (sum_r c_r Hess delta_r) w, one directional derivative of H^T c along
  w (the rows are gradients: delta_r's Hessian is symmetric): in closed form for cables,
  by a fourth-order central difference for other rows; grad_q mu_l.delta_d = H_d^T mu_l.
* commands: a force row's command enters as lambda_f: h H_f mu_v; an equality row's
  displacement command as t_d: mu_l (zero where the command was clipped to its course).
  A target clipped to the rate bound t_d = delta_d(q) + c (``max_displacement_change``
  measured from the step's start) follows q: delta_d cancels from F2, and so does its
  H_d^T mu_l.
* mu_e, lam_e (Lamé parameters, per element): f and K_s are linear in them, so
  -mu_v.(a_k K_s^e v' - h f^e) evaluated with unit parameters (the corotational laws' two
  parts come out of the same reverse pass); E and nu by the chain rule.
* alpha: dF1/dalpha = h M v'; beta: dF1/dbeta = h K_s v'.
* density rho (M and g scale with it): dF1/drho = (a_m M v' - M v - h g) / rho.
* a constant nodal force f_ext: h mu_v.
* cable routing points P (rest positions of the cables' points, :mod:`pliant.diff.routing`):
  h grad_P (lambda.H(q; P) mu_v) - h grad_P (mu_l.H_d(q; P) v') - grad_P (mu_l.delta_d(q; P)).
* rest positions X (with the embedding of the constraint points, their barycentric weights,
  held): the elements' g, V and rest frames and the lumped masses read X (complex step
  again), and a row's rest value delta_d = g(x) - g(X) gives H_d(X)^T mu_l.

Contacts (no rigid bodies) enter at the forward solve's contact states
(:mod:`pliant.diff.contact`): closed normals and sticking tangents as equality rows, sliding
friction along its slip; the block solve then has kinematic rows K, force rows G and the
sliding contacts' stiffening (:meth:`StepAdjoint._contact_adjoint`).

What is held: the active set of the actuator bounds (a command crossing a bound is a kink; a
force command exactly at its bound gets the derivative from inside the bounds, the one-sided
derivative a bound-constrained optimiser needs);
the "lagged" policy is refused (its A is an earlier step's, not a function of this one).
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass

import numba
import numpy as np

from pliant.constraints.base import actuator_bounds, change_reference
from pliant.constraints.cable import CableActuator, CableBundle
from pliant.diff.contact import held_contacts
from pliant.diff.elements import (
    body_shape,
    check_material,
    complex_step_gradient,
    element_terms,
    frame_local_nodes,
    nodal_sum,
    rest_shape,
)
from pliant.diff.kernels import corotational_adjoint_terms
from pliant.diff.routing import routing_gradient
from pliant.errors import ModelError
from pliant.fem import kernels as fem_kernels
from pliant.fem.body import PARALLEL_MIN_TETS, Linearisation, TetBody
from pliant.fem.loads import NodalForces
from pliant.fem.material import NEO_HOOKEAN
from pliant.model import Model, State
from pliant.solvers.linear import SparseCholesky, sparse_cholesky

#: What a step's adjoint can differentiate besides the state it starts from.
PARAMETERS = (
    "controls",
    "young_modulus",
    "poisson_ratio",
    "density",
    "rayleigh_mass",
    "rayleigh_stiffness",
    "external_forces",
    "rest_positions",
    "cable_routing",
    "friction",
)

# Fourth-order central difference of the rows' Jacobian along a direction, step relative to
# the body's size: truncation ~ (step)^4, round-off ~ 1e-16 / step.
_ROW_STEP = 1e-3


def check_parameters(wrt) -> tuple[str, ...]:
    names = (wrt,) if isinstance(wrt, str) else tuple(wrt)
    unknown = [n for n in names if n not in PARAMETERS]
    if unknown:
        raise ModelError(
            f"cannot differentiate with respect to {unknown}; choose from {PARAMETERS}"
        )
    return names


def check_has_mass(body) -> None:
    """ModelError for the density gradient of a massless body (mass="none"): it has no density
    to vary (M and its weight are 0 whatever the density)."""
    if getattr(body, "massless", False):
        raise ModelError("a massless body (mass='none') has no density to differentiate")


def check_model(model: Model) -> None:
    """ModelError naming what pliant.diff does not differentiate in `model`."""
    if not isinstance(model, Model):
        raise ModelError(f"pliant.diff differentiates a pliant Model, got {type(model).__name__}")
    body = model.body
    if not isinstance(body, TetBody):
        raise ModelError(
            f"pliant.diff differentiates tetrahedral bodies, got {type(body).__name__}"
        )
    check_material(body)
    body.uniform_rayleigh("pliant.diff")
    missing = [
        what
        for what, present in (
            (
                "contacts whose points are not linear in the nodes",
                model.contacts is not None and not model.contacts.points.linear,
            ),
            (
                "contacts between pieces of the body (SurfaceContact)",
                model.contacts is not None and bool(model.contacts.surfaces),
            ),
            ("drivers", bool(model.drivers)),
            ("rigid bodies", bool(model.rigid_bodies)),
            ("attachments", bool(model.attachments)),
            ("membranes", bool(body.membranes)),
            ("projections", body.projection is not None),
            (
                "loads other than NodalForces",
                any(not isinstance(a.load, NodalForces) for a in body.loads),
            ),
        )
        if present
    ]
    if missing:
        raise ModelError(
            f"{model.name}: pliant.diff does not differentiate {', '.join(missing)} yet"
            " (see docs/diff.md)"
        )


@dataclass(frozen=True)
class ActuatorRows:
    """How each actuator row entered a step (see the module docstring).

    equality: its lambda was solved for a displacement target (else it was given);
    command_enters: its command is that target or that force (not clipped, not replaced);
    follows_state: its target is the rate bound delta(q) +- max_displacement_change measured
    from the step's own start (change_reference "last"), so that delta_d(q) cancels from F2.
    A rate bound measured from the step before ("lagged") is held: its state is not (q, v)."""

    equality: np.ndarray
    command_enters: np.ndarray
    follows_state: np.ndarray

    @classmethod
    def classify(
        cls, model: Model, commands: np.ndarray, actuation: np.ndarray, state: State
    ) -> ActuatorRows:
        """Read the rows' roles from the forward step's commands and forces."""
        acts = model.actuators
        previous = change_reference(acts, state)
        lo, hi, dmin, dmax = actuator_bounds(acts, previous)
        displacement = np.array([a.mode == "displacement" for a in acts], dtype=bool)
        inside_force = (actuation > lo) & (actuation < hi)
        commanded = np.clip(commands, lo, hi)
        force_free = ~displacement & (actuation == commanded)
        equality = np.where(displacement, inside_force, ~force_free)
        enters = np.where(
            displacement,
            equality & (commands > dmin) & (commands < dmax),
            # A force command exactly at its bound enters with the inside (one-sided)
            # derivative: what a projected-gradient method such as L-BFGS-B needs there.
            force_free & (commands >= lo) & (commands <= hi),
        )
        change = np.array([a.max_displacement_change or np.nan for a in acts])
        last = np.array(
            [getattr(a, "change_reference", "last") == "last" for a in acts], dtype=bool
        )
        target = np.clip(commands, dmin, dmax)
        rate = ((target == dmax) & (dmax == previous + change)) | (
            (target == dmin) & (dmin == previous - change)
        )
        follows = equality & displacement & last & rate & (state.displacement.size == len(acts))
        return cls(equality, enters, follows)


def full_rows_t(model: Model, x: np.ndarray, coefficients: np.ndarray) -> np.ndarray:
    """H(x)^T c over every node (n, 3), for one coefficient per actuator row (the cables'
    rows from their bundle at once)."""
    n = model.body.n_nodes
    coefficients = np.asarray(coefficients, dtype=float)
    cables, bundle, others = _cables(model)
    parts = []
    if cables.size and np.any(coefficients[cables]):
        rows = bundle.jacobian(x)
        parts.append((rows.nodes, coefficients[cables][:, None, None] * rows.values))
    for i in np.flatnonzero(others & (coefficients != 0.0)):
        rows = model.actuators[i].jacobian(x)
        parts.append((rows.nodes[0], coefficients[i] * rows.values[0]))
    out = np.zeros((n, 3))
    for nodes, values in parts:  # bincount: rows repeat nodes, np.add.at is slow at it
        flat, v = nodes.ravel(), values.reshape(-1, 3)
        for i in range(3):
            out[:, i] += np.bincount(flat, v[:, i], n)
    return out


def row_hessian_product(
    model: Model, x: np.ndarray, coefficients: np.ndarray, direction: np.ndarray
) -> np.ndarray:
    """(sum_r c_r Hess delta_r(x)) d (n, 3): the derivative of H(x)^T c along d. Cables in
    closed form (their bundle's geometric stiffness applied segment by segment: Hess delta =
    -Hess L, whose segment blocks are (I - u u^T) / l), other rows by a fourth-order
    central difference."""
    out = np.zeros_like(x)
    coefficients = np.asarray(coefficients, dtype=float)
    size = float(np.max(np.abs(direction)))
    if size == 0.0 or not np.any(coefficients):
        return out
    cables, bundle, others_mask = _cables(model)
    if cables.size and np.any(coefficients[cables]):
        out += bundle.geometric_product(x, coefficients[cables], direction)
    others = np.where(others_mask, coefficients, 0.0)
    if np.any(others):
        eps = _ROW_STEP * model.body.extent / size
        at = [full_rows_t(model, x + k * eps * direction, others) for k in (-2, -1, 1, 2)]
        out += (at[0] - 8.0 * at[1] + 8.0 * at[2] - at[3]) / (12.0 * eps)
    return out


_CABLES: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _cables(model: Model) -> tuple[np.ndarray, CableBundle | None, np.ndarray]:
    """The model's cable actuators (indices), their bundle and which actuators are not
    cables; cached while the cables and their points are the same objects (a design step may
    replace them)."""
    index = [i for i, a in enumerate(model.actuators) if isinstance(a, CableActuator)]
    key = tuple(
        (id(a), id(a.points), id(a.points.weights), id(a.pull_point))
        for a in (model.actuators[i] for i in index)
    ) + (len(model.actuators),)
    cached = _CABLES.get(model)
    if cached is None or cached[0] != key:
        bundle = CableBundle([model.actuators[i] for i in index]) if index else None
        others = np.ones(len(model.actuators), dtype=bool)
        others[index] = False
        cached = _CABLES[model] = (key, np.array(index, dtype=np.int64), bundle, others)
    return cached[1:]


def lame_to_young_poisson(mu: np.ndarray, lam: np.ndarray, mu_bar, lam_bar):
    """Cotangents of (E, nu) per element from those of the Lamé parameters."""
    e = mu * (3.0 * lam + 2.0 * mu) / (lam + mu)
    nu = lam / (2.0 * (lam + mu))
    e_bar = (mu_bar * mu + lam_bar * lam) / e
    dmu_dnu = -e / (2.0 * (1.0 + nu) ** 2)
    dlam_dnu = e * (1.0 + 2.0 * nu * nu) / ((1.0 + nu) ** 2 * (1.0 - 2.0 * nu) ** 2)
    return e_bar, mu_bar * dmu_dnu + lam_bar * dlam_dnu


class StepAdjoint:
    """The adjoint of the step from `state` under `commands` that gave `new` (whose
    velocities and actuator forces it reads): the linearisation at `state`, A factorised,
    the constraint rows. :meth:`vjp` maps cotangents of (q', v') to those of the inputs.

    Args:
        model: the robot (checked by :func:`check_model`).
        dt: the solver's time step h.
        state: the state the step started from.
        commands: the actuator commands of the step (in the actuators' modes).
        new: the state the step returned.
        linearisation: the body linearised at `state` with its velocities, when the forward
            step's is at hand (``solver.system.lin`` after the step); else computed.
        factor: A factorised, when the forward step's is at hand
            (``solver.system.hand_over()`` after a "fresh" step); else A is factorised, into
            `workspace` when given (a factorisation object of the body's pattern, reused
            across steps) or a new one.
    """

    def __init__(
        self,
        model: Model,
        dt: float,
        state: State,
        commands: np.ndarray,
        new: State,
        *,
        linearisation: Linearisation | None = None,
        factor: SparseCholesky | None = None,
        workspace: SparseCholesky | None = None,
    ) -> None:
        body = model.body
        self.model, self.h = model, float(dt)
        self.q, self.v = state.positions, state.velocities
        self.v_new = body.gather(new.velocities)
        self.lam = np.asarray(new.actuation, dtype=float)
        self.rows = ActuatorRows.classify(model, np.asarray(commands, float), self.lam, state)
        h = self.h
        alpha, beta = body.uniform_rayleigh("the differentiable step (pliant.diff)")
        self.a_m = 1.0 + h * alpha
        self.a_k = h * beta + h * h
        self.lin = linearisation or body.linearise(self.q, self.v, time=state.time)
        if factor is None:
            data = self.a_k * body.stiffness_data(self.lin) + self.a_m * body.mass_data
            factor = workspace or sparse_cholesky(body.pattern.indptr, body.pattern.indices)
            factor.factorize(data)
        self.factor = factor
        space = model.constraint_space(self.q, roles=("actuator",))
        self.ht = space.jacobian_t[:, space.slices["actuator"]]
        self.contacts = held_contacts(model, self.h, state, new)

    def vjp(
        self, dq_new: np.ndarray, dv_new: np.ndarray, wrt: tuple[str, ...] = ()
    ) -> dict[str, np.ndarray | float]:
        """Cotangents of the step's inputs for cotangents (n, 3) of q' and v': always
        "positions" and "velocities" (n, 3) of the state it started from, and those of the
        parameters `wrt` (:data:`PARAMETERS`): "controls" (n_a,), "young_modulus" and
        "poisson_ratio" per element (m,), "density", "rayleigh_mass", "rayleigh_stiffness"
        (floats), "external_forces" and "rest_positions" (n, 3), "cable_routing" (P, 3) (the
        layout of :func:`pliant.diff.routing.routing_points`), "friction" (one per obstacle
        shape of the model's contacts)."""
        model, body, h = self.model, self.model.body, self.h
        self._lame = None  # this cotangent's (E, nu) shares, computed once for both
        self._unit = None  # the corotational kernel's unit-law terms (m, 2), when it ran
        d = self.rows.equality
        vbar = body.gather(dv_new) + h * body.gather(dq_new)
        # Equality rows: what they hold (K^T) and how they push (G^T); the held contacts'
        # after the actuators' (pliant.diff.contact: G = K but for sliding contacts).
        held = self.contacts
        mu_l = np.zeros(self.lam.size)
        if held is None:
            cols = self.factor.solve(np.column_stack([vbar, self.ht[:, d]]))
            mu_v = cols[:, 0]
            if d.any():
                a_inv_hd = cols[:, 1:]
                w_dd = h * h * (self.ht[:, d].T @ a_inv_hd)
                mu_l[d] = np.linalg.solve(0.5 * (w_dd + w_dd.T), h * (self.ht[:, d].T @ mu_v))
                mu_v = mu_v - h * (a_inv_hd @ mu_l[d])
        else:
            mu_v, mu_l[d], mu_c = self._contact_adjoint(vbar, held)
        mu_full, v_full = body.scatter(mu_v), body.scatter(self.v_new)
        out: dict[str, np.ndarray | float] = {"velocities": body.scatter(body.mass_matvec(mu_v))}
        # Positions: elements (complex step), then the rows' own dependence on q.
        shape, local = body_shape(body), frame_local_nodes(body)
        tets = body.tets
        mu_e, v_e = mu_full[tets], v_full[tets]

        dq = dq_new - nodal_sum(body, self._element_gradient(mu_full, v_full, shape, local))
        # lambda of every row multiplies H(q): -h lambda.H(q) mu_v, and h mu_l.H_d(q) v'.
        dq += h * row_hessian_product(model, self.q, self.lam, mu_full)
        dq -= h * row_hessian_product(model, self.q, mu_l, v_full)
        dq -= full_rows_t(model, self.q, np.where(self.rows.follows_state, 0.0, mu_l))
        if held is not None:  # a closed contact's gap at the step's start follows q
            dq -= body.scatter(held.kinematic[:, held.gap] @ mu_c[held.gap])
        out["positions"] = dq
        for name in wrt:
            out[name] = self._parameter(name, mu_v, mu_l, mu_e, v_e, shape, local)
        return out

    def _contact_adjoint(self, vbar, held):
        """(mu_v, mu_l of the actuators' equality rows, mu of the contacts' rows) with the
        held contacts (:mod:`pliant.diff.contact`): A mu_v + R z + h K^T mu_l = vbar,
        R^T mu_v = C^-1 z, G mu_v = 0."""
        h, d = self.h, self.rows.equality
        kin = np.hstack([self.ht[:, d], held.kinematic])
        push = np.hstack([self.ht[:, d], held.force])
        s = held.stiffness.size
        cols = self.factor.solve(np.column_stack([vbar, held.across, kin]))
        a_r, a_k = cols[:, 1 : 1 + s], h * cols[:, 1 + s :]
        across = np.column_stack([a_r, a_k])
        system = np.vstack([held.across.T @ across, push.T @ across])
        system[:s, :s] += np.diag(1.0 / held.stiffness)
        rhs = np.concatenate([held.across.T @ cols[:, 0], push.T @ cols[:, 0]])
        w = np.linalg.solve(system, rhs)
        n_d = int(d.sum())
        return cols[:, 0] - across @ w, w[s : s + n_d], w[s + n_d :]

    def _unit_law_terms(self, v_full: np.ndarray, mu_e: np.ndarray) -> list[np.ndarray]:
        """-mu_e.(a_k K_s^e v' - h f^e) per element with (mu, lam) = (1, 0) and (0, 1): f and
        K_s are linear in the Lamé parameters (the compiled kernel, twice)."""
        body, h = self.model.body, self.h
        m = body.n_elements
        out = []
        for mu, lam in ((np.ones(m), np.zeros(m)), (np.zeros(m), np.ones(m))):
            forces, kv = np.empty((m, 4, 3)), np.empty((m, 4, 3))
            fem_kernels.internal_forces(
                self.q,
                v_full,
                body.tets,
                body.grads,
                body.volumes,
                mu,
                lam,
                body.material.kernel_tag,
                body.frame_nodes,
                body.rest_frames,
                forces,
                kv,
                np.empty((m, 3, 3)),
                np.empty(m),
            )
            out.append(-np.einsum("mai,mai->m", self.a_k * kv - h * forces, mu_e))
        return out

    def _element_gradient(self, mu_full, v_full, shape, local) -> np.ndarray:
        """grad_q of sum_e mu_e.(a_k K_s(q) v' - h f(q)) per element corner (m, 4, 3): in
        reverse mode, compiled, for the corotational laws (with the unit-law terms, kept for
        E and nu), by complex step on the NumPy reference otherwise."""
        body, h = self.model.body, self.h
        tag = body.material.kernel_tag
        if tag != NEO_HOOKEAN:
            m = body.n_elements
            out, self._unit = np.empty((m, 4, 3)), np.empty((m, 2))
            frames = np.zeros((m, 3), np.int64) if local is None else local.astype(np.int64)
            # One thread below the size where the body's own kernels wake the others.
            saved = numba.get_num_threads()
            if m < PARALLEL_MIN_TETS:
                numba.set_num_threads(1)
            try:
                corotational_adjoint_terms(
                    self.q,
                    v_full,
                    mu_full,
                    body.tets,
                    body.grads,
                    body.volumes,
                    body.mu,
                    body.lam,
                    tag,
                    frames,
                    body.rest_frames,
                    self.lin.frames,
                    self.lin.dets,
                    self.a_k,
                    h,
                    out,
                    self._unit,
                )
            finally:
                numba.set_num_threads(saved)
            return out
        mu_e, v_e = mu_full[body.tets], v_full[body.tets]

        def element_value(x):
            f, kw = element_terms(body, x, v_e, shape, local, body.mu, body.lam)
            return np.einsum("...mai,mai->...m", self.a_k * kw - h * f, mu_e)

        return complex_step_gradient(element_value, self.q[body.tets])

    def _parameter(self, name, mu_v, mu_l, mu_e, v_e, shape, local):
        body, h = self.model.body, self.h
        v_new, v = self.v_new, body.gather(self.v)
        if name == "controls":
            force_rows = ~self.rows.equality
            ctrl = np.where(force_rows, h * (self.ht.T @ mu_v), mu_l)
            return np.where(self.rows.command_enters, ctrl, 0.0)
        if name in ("young_modulus", "poisson_ratio"):
            if self._lame is None:
                unit = (
                    self._unit.T
                    if self._unit is not None
                    else self._unit_law_terms(body.scatter(v_new), mu_e)
                )
                self._lame = lame_to_young_poisson(body.mu, body.lam, *unit)
            return self._lame[0] if name == "young_modulus" else self._lame[1]
        if name == "rayleigh_mass":
            return float(-h * mu_v @ body.mass_matvec(v_new))
        if name == "rayleigh_stiffness":
            return float(-h * mu_v @ body.stiffness_matvec(self.lin, v_new))
        if name == "density":
            check_has_mass(body)
            g = body.gather(body.gravity_forces())
            term = self.a_m * body.mass_matvec(v_new) - body.mass_matvec(v) - h * g
            return float(-(mu_v @ term) / body.density)
        if name == "external_forces":
            return body.scatter(h * mu_v)
        if name == "friction":  # one coefficient per obstacle shape (pliant.diff.contact)
            out = np.zeros(len(self.model.contacts.shapes) if self.model.contacts else 0)
            held = self.contacts
            if held is not None:
                np.add.at(out, held.friction_shape, held.friction.T @ mu_v)
            return out
        if name == "cable_routing":
            held = np.where(self.rows.follows_state, 0.0, mu_l)
            products = [(h * self.lam, body.scatter(mu_v)), (-h * mu_l, body.scatter(v_new))]
            return routing_gradient(self.model, self.q, -held, products)
        return self._rest_positions(mu_v, mu_l, mu_e, v_e, local)

    def _rest_positions(self, mu_v, mu_l, mu_e, v_e, local):
        """grad_X of -mu.F: elements and lumped masses by complex step, rows' rest values."""
        model, body, h = self.model, self.model.body, self.h
        if body.mass_type == "consistent":
            raise ModelError("rest-position gradients need a lumped or uniform mass")
        lumped = body.mass_type == "lumped"
        # Each element's share of the mass terms: rho V_e / 4 sum_a mu_a.(a_m v'_a - v_a - h g).
        v_old = body.scatter(body.gather(self.v))
        per_node = self.a_m * v_e - v_old[body.tets] - h * body.gravity
        mass_share = np.einsum("mai,mai->m", mu_e, per_node) * body.density / 4.0
        x = self.q[body.tets]

        def element_value(rest):
            shape = rest_shape(body, rest, local)
            f, kw = element_terms(body, x, v_e, shape, local, body.mu, body.lam)
            value = np.einsum("...mai,mai->...m", self.a_k * kw - h * f, mu_e)
            return value + shape.volumes * mass_share if lumped else value

        grad = -nodal_sum(
            body, complex_step_gradient(element_value, body.rest_positions[body.tets])
        )
        return grad + full_rows_t(model, body.rest_positions, mu_l)
