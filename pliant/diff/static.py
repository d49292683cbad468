"""Gradients of a static equilibrium by the implicit-function theorem.

At the equilibrium of :class:`pliant.solvers.StaticSolver` (free DoFs q, actuator rows as in
:mod:`pliant.diff.step`: equality rows d with lambda_d unknown, force rows with lambda known)

    R1 = f(q; p) + g + f_ext + H(q)^T lambda = 0,     R2 = delta_d(q) - t_d = 0.

With K_c = -dR1/dq = K(q) - sum_r lambda_r Hess delta_r (the exact material tangent, from
complex-step element Jacobians, whatever the law: the large-frame corotational one is not
symmetric; and the cables' geometric stiffness), dR/dy = [[-K_c, H_d^T], [H_d, 0]]. For a
loss L(q), the adjoint mu = (mu_q, mu_l) solves dR/dy^T mu = (dL/dq, 0):

    (H_d K_c^-T H_d^T) mu_l = H_d K_c^-T qbar,    mu_q = K_c^-T (H_d^T mu_l - qbar),

and each parameter gets pbar = -(dR/dp)^T mu: mu_e, lam_e: -mu_q.f^e(unit parameters);
(the held nodes stay at their rest positions, so their share of dL/dq and of
-grad_q mu.R joins the rest positions');
density: -mu_q.g / rho; a force command: -H_f mu_q; a displacement target: mu_l; a nodal force:
-mu_q; rest positions: -grad_X mu_q.(f + g) + H_d(X)^T mu_l; cable routing points P:
-grad_P (lambda.H(q; P) mu_q + mu_l.delta_d(q; P)) (:mod:`pliant.diff.routing`). For a law
homogeneous of degree one in E (both here), q depends on f_ext / E only, so
E dq/dE = -f_ext . dq/df_ext: for a linear response, d delta / dE = -delta / E (the tests
check both).

Closed contacts (:func:`pliant.diff.contact.closed_contacts`) join the equality rows d with
their states held, at zero target: each gap held closed, each sticking point held where it is
(its two tangential rows). A sliding contact (only for ``StaticSolver(slip="solve")``, whose
slip delta_t = t.P (q - q_0) runs from the start q_0; the default solver's slip is each
Newton update's, and its sliding equilibrium a function of the iterations' path) pushes with
mu lambda_n s, s = -delta_t / |delta_t|: its normal row's force direction is
G = n.P + mu s.(t.P) (K = n.P what it holds), and s turning with the slip adds
sum c r r^T to K_c (r = e.(t.P), e across the slip, c = mu lambda_n / |delta_t|). With
z = -C R^T mu_q the adjoint is

    mu_q = K_c^-T (R z + K^T mu_l - qbar),   R^T mu_q + C^-1 z = 0,   G mu_q = 0,

one LU solve on [qbar, R, K^T] and a dense system for (z, mu_l). The friction coefficient's
cotangent is -lambda_n s.(t.P) mu_q per sliding contact (zero for sticking ones), and the
start's, "start_positions", that of the slip's q_0: K_t^T mu_l of the sticking rows and
-c r (r.mu_q) of the sliding contacts, on the free nodes.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from pliant.diff.contact import closed_contacts
from pliant.diff.elements import (
    body_shape,
    complex_step_gradient,
    complex_step_jacobian,
    element_terms,
    frame_local_nodes,
    nodal_sum,
    rest_shape,
)
from pliant.diff.parameters import check_regions, region_sum
from pliant.diff.routing import routing_gradient
from pliant.diff.step import (
    ActuatorRows,
    check_has_mass,
    check_model,
    check_parameters,
    full_rows_t,
    lame_to_young_poisson,
    row_hessian_product,
)
from pliant.errors import ModelError
from pliant.model import Model, State
from pliant.solvers.static import StaticSolver


def static_gradient(
    model: Model,
    solver: StaticSolver,
    equilibrium: State,
    commands: np.ndarray,
    positions_gradient: np.ndarray,
    *,
    wrt: tuple[str, ...] | str = ("controls",),
    regions: np.ndarray | None = None,
    start: State | None = None,
) -> dict[str, np.ndarray | float]:
    """Gradients of a loss L(q) of the equilibrium `equilibrium` (solved by `solver` under
    `commands`), given dL/dq (n, 3), with respect to `wrt` (as
    :func:`pliant.diff.rollout_gradient`; the Rayleigh coefficients do not enter a static
    equilibrium and get 0). `start`: the state the solve started from, for a
    ``StaticSolver(slip="solve")`` with contacts (its slip is measured from it); the result
    then has "start_positions" (n, 3) too, the cotangent of the start's positions.

    Raises:
        ModelError: unsupported model, solver or parameter; wrong shapes.
    """
    check_model(model)
    if not isinstance(solver, StaticSolver) or solver.model is not model:
        raise ModelError("static_gradient needs the model's StaticSolver")
    names = check_parameters(wrt)
    regions = check_regions(model, regions)
    body = model.body
    grad_q = np.asarray(positions_gradient, dtype=float)
    if grad_q.shape != (body.n_nodes, 3):
        raise ModelError(f"positions_gradient must be ({body.n_nodes}, 3), got {grad_q.shape}")
    commands = np.asarray(commands, dtype=float)
    if commands.shape != (model.n_actuators,):
        raise ModelError(f"commands must be ({model.n_actuators},), got {commands.shape}")
    q, lam = equilibrium.positions, np.asarray(equilibrium.actuation, dtype=float)
    rows = ActuatorRows.classify(model, commands, lam, equilibrium)
    d = rows.equality
    shape, local = body_shape(body), frame_local_nodes(body)
    x = q[body.tets]

    def forces(xe):
        return element_terms(body, xe, None, shape, local, body.mu, body.lam)[0]

    k_c = _tangent(model, q, lam, -complex_step_jacobian(forces, x))
    lu = spla.splu(k_c.T.tocsc())
    space = model.constraint_space(q, roles=("actuator",))
    ht = space.jacobian_t[:, space.slices["actuator"]]
    qbar = body.gather(grad_q)
    # Equality rows: the actuators', then the closed contacts' at their held states.
    if start is not None and solver.slip != "solve":
        raise ModelError(
            "static_gradient: start= is the state a StaticSolver(slip='solve') started from;"
            " this solver measures slip over each Newton update"
        )
    if start is None and solver.slip == "solve" and model.contacts is not None:
        raise ModelError(
            "static_gradient of a StaticSolver(slip='solve') with contacts needs start=, the"
            " state its solve started from (the contacts' slip is measured from it)"
        )
    contacts = closed_contacts(model, equilibrium, start)
    mu_l, mu_c, mu_q = np.zeros(lam.size), np.zeros(0), None
    if contacts is None:
        rows_d = push_d = ht[:, d]
        across, stiffness = np.zeros((ht.shape[0], 0)), np.zeros(0)
    else:
        rows_d, push_d = (np.hstack([ht[:, d], c]) for c in (contacts.rows, contacts.force))
        across, stiffness = contacts.across, contacts.stiffness
    s = stiffness.size
    cols = lu.solve(np.column_stack([qbar, across, rows_d]))
    if rows_d.shape[1] + s:
        # -(K_c + R C R^T)^T mu_q + K^T mu_l = qbar, G mu_q = 0 (G: the rows' force
        # directions), with z = -C R^T mu_q: mu_q = K_c^-T (R z + K^T mu_l - qbar).
        lhs = cols[:, 1:]
        system = np.vstack([across.T @ lhs, push_d.T @ lhs])
        system[:s, :s] += np.diag(1.0 / stiffness)
        w_all = np.linalg.solve(system, np.concatenate([across.T, push_d.T]) @ cols[:, 0])
        mu_l[d], mu_c = w_all[s : s + int(d.sum())], w_all[s + int(d.sum()) :]
        mu_q = lhs @ w_all - cols[:, 0]
    else:
        mu_q = -cols[:, 0]
    mu_full = body.scatter(mu_q)
    mu_e = mu_full[body.tets]
    out: dict[str, np.ndarray | float] = {}
    for name in names:
        if name == "controls":
            out[name] = np.where(rows.command_enters, np.where(d, mu_l, -(ht.T @ mu_q)), 0.0)
        elif name in ("young_modulus", "poisson_ratio"):
            ones, zeros = np.ones(body.n_elements), np.zeros(body.n_elements)
            bars = [
                -np.einsum("mai,mai->m", mu_e, element_terms(body, x, None, shape, local, a, b)[0])
                for a, b in ((ones, zeros), (zeros, ones))
            ]
            e_bar, nu_bar = lame_to_young_poisson(body.mu, body.lam, *bars)
            out[name] = region_sum(e_bar if name == "young_modulus" else nu_bar, regions)
        elif name == "density":
            check_has_mass(body)
            out[name] = float(-(mu_q @ body.gather(body.gravity_forces())) / body.density)
        elif name in ("rayleigh_mass", "rayleigh_stiffness"):
            out[name] = 0.0
        elif name == "external_forces":
            out[name] = -mu_full
        elif name == "friction":  # one per obstacle shape: the sliding contacts' share
            out[name] = np.zeros(len(model.contacts.shapes) if model.contacts else 0)
            if contacts is not None:
                if contacts.friction.shape[1] < contacts.closed - contacts.sticking:
                    raise ModelError(
                        "static_gradient: the friction coefficient at a frictionless closed"
                        " contact needs its slip over the solve (friction would start against"
                        " it): a StaticSolver(slip='solve') with start=, and a contact that"
                        " slipped"
                    )
                np.add.at(out[name], contacts.friction_shape, -(contacts.friction.T @ mu_q))
        elif name == "cable_routing":
            out[name] = routing_gradient(model, q, -mu_l, [(-lam, mu_full)])
        else:
            out[name] = _rest_positions(model, q, mu_e, mu_l, local)
            out[name] += _held_nodes(model, q, lam, grad_q, mu_e, mu_full, mu_l, shape, local)
            if contacts is not None:  # a contact point carried by held nodes
                held = (body.free_index < 0).reshape(-1, 3)
                out[name] -= np.where(held, contacts.full_t(mu_c, body.n_nodes), 0.0)
    if start is not None:
        out["start_positions"] = (
            np.zeros_like(grad_q)
            if contacts is None
            else _start_positions(body, contacts, mu_q, mu_c)
        )
    return out


def _start_positions(body, contacts, mu_q, mu_c) -> np.ndarray:
    """The cotangent of the start's free nodes (slip="solve": the slip t.P (q - q_0) is
    measured from them): a sticking row held at zero slip gives K_t^T mu_c, a sliding
    contact's friction turning with its slip -c r (r.mu_q). The held nodes do not slip (they
    stay at the start's positions)."""
    tangential = np.ones(contacts.rows.shape[1], dtype=bool)
    tangential[contacts.normal] = False
    out = contacts.full_t(np.where(tangential, mu_c, 0.0), body.n_nodes)
    out -= contacts.across_full_t(contacts.stiffness * (contacts.across.T @ mu_q), body.n_nodes)
    return np.where((body.free_index >= 0).reshape(-1, 3), out, 0.0)


def _held_nodes(model, q, lam, grad_q, mu_e, mu_full, mu_l, shape, local) -> np.ndarray:
    """The held nodes stay at their rest positions: dL/dq there less grad_q (mu.R) there."""
    body = model.body

    def element_value(x):
        f = element_terms(body, x, None, shape, local, body.mu, body.lam)[0]
        return np.einsum("...mai,mai->...m", f, mu_e)

    through = nodal_sum(body, complex_step_gradient(element_value, q[body.tets]))
    through += row_hessian_product(model, q, lam, mu_full) + full_rows_t(model, q, mu_l)
    held = (body.free_index < 0).reshape(-1, 3)
    return np.where(held, grad_q - through, 0.0)


def _tangent(model: Model, q: np.ndarray, lam: np.ndarray, blocks: np.ndarray) -> sp.csc_matrix:
    """K_c on the free DoFs: element blocks (m, 12, 12) of -df/dx and the actuators' load
    stiffness at forces `lam`."""
    body = model.body
    dofs = body.free_index[(3 * body.tets[:, :, None] + np.arange(3)).reshape(-1, 12)]
    rows = np.repeat(dofs[:, :, None], 12, axis=2)
    cols = np.repeat(dofs[:, None, :], 12, axis=1)
    keep = (rows >= 0) & (cols >= 0)
    n = body.n_free
    k = sp.coo_matrix((blocks[keep], (rows[keep], cols[keep])), shape=(n, n)).tocsc()
    pattern = model.geometric_pattern()
    if pattern is not None:
        values = model.geometric_stiffness(q, lam)
        k = k + sp.coo_matrix((values, pattern), shape=(n, n)).tocsc()
    return k


def _rest_positions(model: Model, q, mu_e, mu_l, local) -> np.ndarray:
    body = model.body
    if body.mass_type == "consistent":
        raise ModelError("rest-position gradients need a lumped or uniform mass")
    lumped = body.mass_type == "lumped"
    weight = np.einsum("mai,i->m", mu_e, body.gravity) * body.density / 4.0
    x = q[body.tets]

    def element_value(rest):
        shape = rest_shape(body, rest, local)
        f = element_terms(body, x, None, shape, local, body.mu, body.lam)[0]
        value = np.einsum("...mai,mai->...m", f, mu_e)
        return value + shape.volumes * weight if lumped else value

    grad = -nodal_sum(body, complex_step_gradient(element_value, body.rest_positions[body.tets]))
    return grad + full_rows_t(model, body.rest_positions, mu_l)
