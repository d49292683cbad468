"""Contact and friction in a step's adjoint, at the forward solution's active set.

A step with contacts (:class:`pliant.constraints.contact.Contacts`, no rigid bodies) solves
Signorini's and Coulomb's laws on the rows of the contacts detected at its start: for
contact i, with p its point, n, t1, t2 its frame and phi its gap at detection,

    delta_n = phi + h n.P v',  delta_t = h t.P v'   (P: the point's weights; still obstacle).

The adjoint differentiates the step with the *contact states of the forward solve held*:

* an open contact (lambda_n = 0) is left out;
* a closed contact (lambda_n > 0) is a bilateral row delta_n = 0: an equality row like a
  displacement-mode actuator's, whose value at the step's start, the gap phi(q), follows the
  state (d phi / dq = n.P, the signed distance's gradient);
* a sticking contact (|lambda_t| < mu lambda_n) adds its two tangential rows, bilateral too
  (delta_t = 0; their value at the step's start is zero whatever q);
* a sliding contact (|lambda_t| = mu lambda_n) pushes with lambda_t = mu lambda_n s along
  s = -delta_t / |delta_t|, against its slip delta_t = delta_t(q) + h t.P v' over the step:
  its normal row pushes along G_n = n.P + mu s.(t.P) while it holds n.P, and the friction's
  turning with the slip, d s / d delta_t = -(I - s s^T) / |delta_t|, stiffens the step:
  d F1 / d v' = A + sum_sliding c r r^T, with r = e.(t.P), e the tangent across the slip,
  c = h^2 mu lambda_n / |delta_t|;
* frictionless contacts (mu = 0) have normal rows only.

So the adjoint's equality rows have kinematic rows K (what they hold at zero) and force rows G
(how their multipliers push), G = K but for sliding contacts, and A gains the sliding
contacts' rank-one terms. With z = C R^T mu_v (R = [r], C = diag(c)), the adjoint
(d F / d y)^T mu = (vbar, 0) reads

    A mu_v + R z + h K^T mu_l = vbar,   R^T mu_v - C^-1 z = 0,   G mu_v = 0,

solved with A's factorisation on the columns [vbar, R, K^T] and a dense system for (z, mu_l)
(:class:`pliant.diff.step.StepAdjoint`).

The contacts are detected again from the step's start state, with the obstacles where they
are now: an obstacle moved between steps by a script must be put back where it was for the
adjoint of that step. What is held besides the states: the contact frames (they turn with
the point on a curved obstacle; exact for planes and the faces of boxes, whose normals do
not) and the detection (the set of contacts within the margin). The friction coefficient's
cotangent is the sliding contacts' h lambda_n s.(t.P) mu_v (HeldContacts.friction). The
gradient is the derivative of the step where no contact changes state under the
perturbation; where one does (a contact opening, a stick turning to slip), the step is not
differentiable and this is the derivative of one of its branches.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pliant.errors import ModelError
from pliant.model import Model, State

#: A contact slides when its friction force is within this relative distance of the cone.
SLIP_TOLERANCE = 1e-8


@dataclass(frozen=True)
class HeldContacts:
    """A step's contact rows at its forward active set (module docstring).

    Attributes:
        kinematic: K^T on the free DoFs (n_free, r): the rows held at zero.
        force: G^T (n_free, r): their force directions (K^T but for sliding contacts).
        gap: (r,) bool, the row is a normal, whose value at the step's start follows q.
        across: R (n_free, s), each sliding contact's tangential row across its slip.
        stiffness: c (s,), h^2 mu lambda_n / |delta_t| of each sliding contact.
        friction: d F1 / d mu_i = -h lambda_n (t.P)^T s of each closed contact that slides
            (frictionless ones slide too) as columns (n_free, f), each with its shape
            (f,): the cotangent of the shape's coefficient is sum h lambda_n s.(t.P) mu_v.
        closed, sticking, sliding: how many contacts were in each state.
    """

    kinematic: np.ndarray
    force: np.ndarray
    gap: np.ndarray
    across: np.ndarray
    stiffness: np.ndarray
    friction: np.ndarray
    friction_shape: np.ndarray
    closed: int
    sticking: int
    sliding: int

    @property
    def n_rows(self) -> int:
        return int(self.gap.size)


def held_contacts(model: Model, dt: float, state: State, new: State) -> HeldContacts | None:
    """The contact rows of the step from `state` that returned `new` (its contact forces),
    or None when it detected no contact or none closed."""
    if model.contacts is None:
        return None
    contact = model.contacts.constraint(state.positions, dt, None)
    if contact is None:
        return None
    lam = new.contact_forces.warm_start(contact.contacts).reshape(-1, 3)
    closed = lam[:, 0] > 0.0
    if not closed.any():
        return None
    mu = contact.friction
    tangential = np.linalg.norm(lam[:, 1:], axis=1)
    friction = closed & (mu > 0.0)
    sliding = friction & (tangential >= mu * lam[:, 0] * (1.0 - SLIP_TOLERANCE))
    sticking = friction & ~sliding
    ht = model.constraint_space(state.positions, [contact], with_distance=False).jacobian_t
    rows = ht.reshape(ht.shape[0], -1, 3)  # (n_free, contact, n t1 t2)
    # Each contact's tangential displacement over the step (its slip, where it slides).
    v_new = model.body.gather(new.velocities)
    slip = contact.distance(state.positions).reshape(-1, 3)[:, 1:]
    slip += dt * np.einsum("fkr,f->kr", rows[:, :, 1:], v_new)
    kinematic, force, gap, across, stiffness = [], [], [], [], []
    pushes, shapes = [], []
    for i in np.flatnonzero(closed):
        normal = rows[:, i, 0]
        kinematic.append(normal)
        gap.append(True)
        if sliding[i]:
            direction = lam[i, 1:] / tangential[i]
            force.append(normal + mu[i] * (rows[:, i, 1:] @ direction))
            across.append(rows[:, i, 1:] @ np.array([-direction[1], direction[0]]))
            stiffness.append(dt * dt * mu[i] * lam[i, 0] / np.linalg.norm(slip[i]))
        else:
            force.append(normal)
        if not sticking[i] and np.linalg.norm(slip[i]) > 0.0:
            # mu's share: the friction force's size, along -slip (also at mu = 0: the
            # derivative from mu > 0, where every closed contact of a frictionless step slides).
            direction = -slip[i] / np.linalg.norm(slip[i])
            pushes.append(dt * lam[i, 0] * (rows[:, i, 1:] @ direction))
            shapes.append(contact.contacts.index_b[i])
        if sticking[i]:
            for r in (1, 2):
                kinematic.append(rows[:, i, r])
                force.append(rows[:, i, r])
                gap.append(False)
    n_free = ht.shape[0]
    return HeldContacts(
        np.column_stack(kinematic),
        np.column_stack(force),
        np.array(gap),
        np.column_stack(across) if across else np.zeros((n_free, 0)),
        np.array(stiffness),
        np.column_stack(pushes) if pushes else np.zeros((n_free, 0)),
        np.array(shapes, dtype=np.int64),
        int(closed.sum()),
        int(sticking.sum()),
        int(sliding.sum()),
    )


@dataclass(frozen=True)
class ClosedContacts:
    """The closed contacts of a static equilibrium at their held states (:func:`closed_contacts`).

    Attributes:
        rows: K^T on the free DoFs (n_free, r): each closed contact's normal n.P and a
            sticking one's tangents t.P, rows held at their value (gap closed, point stuck).
        force: G^T (n_free, r): how their multipliers push (K^T but for a sliding contact's
            normal, n.P + mu s.(t.P)).
        nodes, values: K on every node, (r, 4) nodes with (r, 4, 3) values.
        normal: (r,) bool, the row is a normal (else a sticking contact's tangent).
        across: R (n_free, s), each sliding contact's tangential row across its slip, and
            across_nodes, across_values the same on every node.
        stiffness: c (s,), mu lambda_n / |delta_t| of each sliding contact.
        friction: d R1 / d mu_i = lambda_n (t.P)^T s of each closed contact that slides
            (frictionless ones slide too) as columns (n_free, f), with each one's obstacle
            shape (friction_shape, (f,)).
        closed, sticking, sliding: how many contacts were closed, and of those how many stick
            and how many slide.
    """

    rows: np.ndarray
    force: np.ndarray
    nodes: np.ndarray
    values: np.ndarray
    normal: np.ndarray
    across: np.ndarray
    across_nodes: np.ndarray
    across_values: np.ndarray
    stiffness: np.ndarray
    friction: np.ndarray
    friction_shape: np.ndarray
    closed: int
    sticking: int
    sliding: int

    def full_t(self, coefficients: np.ndarray, n_nodes: int) -> np.ndarray:
        """sum_r c_r K_r on every node (n, 3)."""
        out = np.zeros((n_nodes, 3))
        np.add.at(out, self.nodes, coefficients[:, None, None] * self.values)
        return out

    def across_full_t(self, coefficients: np.ndarray, n_nodes: int) -> np.ndarray:
        """sum_s c_s R_s on every node (n, 3)."""
        out = np.zeros((n_nodes, 3))
        np.add.at(out, self.across_nodes, coefficients[:, None, None] * self.across_values)
        return out


def closed_contacts(
    model: Model, equilibrium: State, start: State | None = None
) -> ClosedContacts | None:
    """The closed contacts of a static equilibrium (:class:`pliant.solvers.StaticSolver`) with
    their states held, as bilateral rows; None without contacts or none closed.

    A static equilibrium with friction depends on its path: a sticking point stays where the
    iterations that led to it left it, a sliding one slides until its friction force reaches
    the cone. Held here: the set of closed contacts (each gap stays closed), each sticking
    contact's point (its two tangential rows held at their value) and each sliding contact's
    state: it slides, its friction mu lambda_n s on the cone against its slip over the solve,
    delta_t = t.P (q - q_0) from the state `start` the solve started from, s = -delta_t /
    |delta_t| (the solve from `start` is one quasi-static step: the static analogue of the
    dynamic step's slip over the step). So a sliding contact's normal row pushes along
    G_n = n.P + mu s.(t.P) while it holds n.P, and the friction's turning with the slip,
    d s / d delta_t = -(I - s s^T) / |delta_t|, stiffens the equilibrium: K_c gains
    sum c r r^T, r = e.(t.P), e across the slip, c = mu lambda_n / |delta_t|. This is the
    derivative of the solve from `start` where no contact changes state; where one would (a
    sliding contact easing to stick) the equilibrium has a kink and this is the derivative
    of its sliding branch.

    With `start` None (the default solver's slip="iteration"), sliding contacts are refused.

    Raises:
        ModelError: a sliding contact (its friction force on the cone, within SLIP_TOLERANCE)
            when `start` is None, or one that did not slip from `start`.
    """
    if model.contacts is None:
        return None
    contact = model.contacts.constraint(equilibrium.positions, None)
    if contact is None:
        return None
    lam = equilibrium.contact_forces.warm_start(contact.contacts).reshape(-1, 3)
    closed = np.flatnonzero(lam[:, 0] > 0.0)
    if closed.size == 0:
        return None
    lam = lam[closed]
    mu = contact.friction[closed]
    tangential = np.linalg.norm(lam[:, 1:], axis=1)
    friction = mu > 0.0
    sliding = friction & (tangential >= mu * lam[:, 0] * (1.0 - SLIP_TOLERANCE))
    held = contact.take(closed)
    ht = model.constraint_space(equilibrium.positions, [held], with_distance=False).jacobian_t
    jac = held.jacobian(equilibrium.positions)
    rows = ht.reshape(ht.shape[0], -1, 3)  # (n_free, contact, n t1 t2)
    slip = None
    if start is not None:
        moved = equilibrium.positions - model.check_state(start).positions
        slip = np.einsum("rpi,rpi->r", jac.values, moved[jac.nodes]).reshape(-1, 3)[:, 1:]
    elif sliding.any():
        raise ModelError(
            f"{model.name}: {int(sliding.sum())} of {closed.size} closed contacts slide (friction"
            " on the cone) at an equilibrium whose slip was measured over each Newton update:"
            " its friction's direction is that of the last updates, a function of the"
            " iterations' path; solve it with StaticSolver(slip='solve') and pass start= to"
            " static_gradient"
        )
    keep, force, across, across_rows, stiffness, pushes, shapes = [], [], [], [], [], [], []
    for k in range(closed.size):
        normal = rows[:, k, 0]
        keep.append(3 * k)
        force.append(normal)
        size = 0.0 if slip is None else float(np.linalg.norm(slip[k]))
        if sliding[k]:
            if size == 0.0:
                raise ModelError(
                    f"{model.name}: a closed contact's friction is on the cone but it did not"
                    " slip from the start state: its static derivative is one-sided"
                )
            s = lam[k, 1:] / tangential[k]
            force[-1] = normal + mu[k] * (rows[:, k, 1:] @ s)
            e = np.array([-s[1], s[0]])
            across.append(rows[:, k, 1:] @ e)
            across_rows.append((3 * k + 1, 3 * k + 2, e))
            stiffness.append(mu[k] * lam[k, 0] / size)
        elif friction[k]:
            keep.extend((3 * k + 1, 3 * k + 2))
            force.extend((rows[:, k, 1], rows[:, k, 2]))
        if not (friction[k] and not sliding[k]) and size > 0.0:
            # mu's share, the friction's size along -slip (at mu = 0 the derivative from
            # mu > 0, where a frictionless closed contact slides).
            pushes.append(lam[k, 0] * (rows[:, k, 1:] @ (-slip[k] / size)))
            shapes.append(held.contacts.index_b[k])
    n_free = ht.shape[0]
    nodes = jac.nodes
    across_values = np.array(
        [e[0] * jac.values[a] + e[1] * jac.values[b] for a, b, e in across_rows]
    ).reshape(-1, *jac.values.shape[1:])
    return ClosedContacts(
        ht[:, keep],
        np.column_stack(force),
        nodes[keep],
        jac.values[keep],
        np.array([r % 3 == 0 for r in keep]),
        np.column_stack(across) if across else np.zeros((n_free, 0)),
        np.array([nodes[a] for a, _, _ in across_rows], dtype=np.int64).reshape(-1, nodes.shape[1]),
        across_values,
        np.array(stiffness),
        np.column_stack(pushes) if pushes else np.zeros((n_free, 0)),
        np.array(shapes, dtype=np.int64),
        int(closed.size),
        int((friction & ~sliding).sum()),
        int(sliding.sum()),
    )
