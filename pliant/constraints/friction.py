"""Frictional contact in the constraint (compliance) space, solved jointly with the actuators.

With delta = W lambda + delta_free (W symmetric positive semi-definite, rows ordered actuators,
effectors, contacts; see :class:`pliant.constraints.condensed.CondensedProblem`), each contact
owns three rows (normal n, tangents t1, t2) and obeys, as in thesis §2.1.3 and SOFA's
GenericConstraintSolver (Duriez et al., IEEE TVCG 12(1), 2006):

    Signorini:  0 <= delta_n  _|_  lambda_n >= 0
    Coulomb:    |lambda_t| <= mu lambda_n;  |lambda_t| < mu lambda_n  =>  delta_t = 0  (stick)
                |lambda_t| = mu lambda_n   =>  delta_t = -nu lambda_t, nu >= 0  (slip)

delta_t is the tangential displacement over the step, so slip opposes the force, the maximal
dissipation principle. Actuator rows follow their mode (force or displacement) and bounds as in
:func:`pliant.constraints.direct.solve_direct`; effector rows are passive (lambda_e = 0).

The solver is projected block Gauss-Seidel (Jean, CMAME 177, 1999): each block (an actuator
row, a contact triple) in turn gets the exact solution of its own law with the other
multipliers frozen. For a contact that is the normal projection max(0, .) followed by the
tangential problem min 1/2 x^T W_tt x + g^T x on the disk |x| <= mu lambda_n, whose solution
satisfies Coulomb's law exactly even for an anisotropic W_tt (a radial clamp of the
unconstrained solution would not).

Gauss-Seidel converges linearly, slowly when W is the compliance of a soft body (its smooth
modes are far more compliant than its local ones: 947 sweeps for 18 sticking nodes of a
cantilever in tests/test_contact.py). Every 8, 16, 32, ... sweeps the solver therefore tries a
jump to the exact solution of the current states of the blocks (separated, sticking, slipping
in a fixed direction; actuators on their command or bound), one dense solve, kept only if it is
admissible: 37 sweeps in that test, exact to round-off. Sweeps decide convergence either way.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, fields

import numpy as np

from pliant.constraints import contact_kernels as kernels
from pliant.constraints.base import (
    Actuator,
    Constraint,
    EmbeddedPoints,
    JacobianRows,
    actuator_bounds,
)
from pliant.constraints.collision import ContactSet
from pliant.constraints.condensed import CondensedProblem
from pliant.errors import ContactConvergenceWarning, ContactError


@dataclass(frozen=True)
class ContactReport:
    """How the Gauss-Seidel iterations ended.

    Attributes:
        iterations: sweeps made.
        residual: largest displacement correction of one block in the last sweep (units of
            delta).
        converged: residual <= tolerance.
    """

    iterations: int = 0
    residual: float = 0.0
    converged: bool = True


@dataclass(frozen=True)
class ContactSolution:
    """lambda for every row (actuators, effectors = 0, contacts), delta = W lambda +
    delta_free, and the report."""

    forces: np.ndarray
    displacement: np.ndarray
    report: ContactReport
    slices: dict[str, slice]

    @property
    def contact_forces(self) -> np.ndarray:
        """(k, 3) multipliers (lambda_n, lambda_t1, lambda_t2) of each contact."""
        return self.forces[self.slices["contact"]].reshape(-1, 3)

    @property
    def actuation(self) -> np.ndarray:
        return self.forces[self.slices["actuator"]]


def check_friction(friction, n_contacts: int) -> np.ndarray:
    """mu as a (k,) array from a scalar or k values; ContactError if any is < 0 or not finite."""
    values = np.asarray(friction, dtype=float).reshape(-1)
    if values.size not in (1, n_contacts):
        raise ContactError(f"expected 1 or {n_contacts} friction coefficients, got {values.size}")
    bad = ~(np.isfinite(values) & (values >= 0.0))
    if np.any(bad):
        i = int(np.argmax(bad))
        raise ContactError(
            f"friction coefficients must be finite and >= 0, got mu = {float(values[i])}"
            f" (contact {i})"
        )
    mu = np.broadcast_to(values, (n_contacts,)).copy()
    return mu


def _check_problem(problem: CondensedProblem) -> tuple[np.ndarray, np.ndarray]:
    w = np.ascontiguousarray(problem.compliance, dtype=float)
    d = np.ascontiguousarray(problem.free_distance, dtype=float)
    r = d.shape[0]
    if w.shape != (r, r) or d.ndim != 1:
        raise ContactError(f"W must be ({r}, {r}) for {r} rows of delta_free, got {w.shape}")
    finite, scale, asymmetry = kernels.matrix_summary(w)
    if not (finite and np.all(np.isfinite(d))):
        raise ContactError("W and delta_free must be finite (the free motion diverged?)")
    if asymmetry > 1e-8 * scale:
        raise ContactError(f"W must be symmetric, |W - W^T| = {asymmetry:.3g} (|W| = {scale:.3g})")
    if r and np.diag(w).min() < -1e-12 * scale:
        i = int(np.argmin(np.diag(w)))
        raise ContactError(f"W is not positive semi-definite: W[{i}, {i}] = {w[i, i]:.3g} < 0")
    return w, d


def solve_contact(
    problem: CondensedProblem,
    friction: np.ndarray | float,
    *,
    actuators: Sequence[Actuator] = (),
    previous_displacement: np.ndarray | None = None,
    initial: np.ndarray | None = None,
    tolerance: float = 1e-9,
    max_iterations: int = 1000,
) -> ContactSolution:
    """Signorini-Coulomb contacts and bounded actuators on delta = W lambda + delta_free.

    Args:
        problem: W and delta_free; its "contact" slice holds 3 rows per contact.
        friction: mu per contact (or one for all).
        actuators: the actuators of the "actuator" rows, in order (commands, modes, bounds).
        previous_displacement: delta_a at the end of the previous step (for the bound on the
            change of delta per step; default zeros).
        initial: warm start, lambda for every row (e.g. the previous actuation and
            ContactForces.warm_start for the contacts); default zeros.
        tolerance: stop when no block's displacement changes by more than this in a sweep
            (units of delta).
        max_iterations: sweeps at most; reaching it warns with ContactConvergenceWarning.
    """
    w, d = _check_problem(problem)
    r = d.shape[0]
    contact_rows = problem.slices["contact"]
    n_rows = contact_rows.stop - contact_rows.start
    if n_rows % 3:
        raise ContactError(f"contact rows come in triples (n, t1, t2), got {n_rows} rows")
    mu = check_friction(friction, n_rows // 3)
    act = problem.slices["actuator"]
    if act.stop - act.start != len(actuators):
        raise ContactError(
            f"{act.stop - act.start} actuator rows but {len(actuators)} actuators were given"
        )
    if not (math.isfinite(tolerance) and tolerance > 0.0):
        raise ContactError(f"tolerance must be finite and > 0, got {tolerance!r}")
    if int(max_iterations) < 1:
        raise ContactError(f"max_iterations must be >= 1, got {max_iterations!r}")
    max_iterations = int(max_iterations)
    lam = np.zeros(r) if initial is None else np.array(initial, dtype=float).reshape(-1)
    if lam.shape != (r,) or not np.all(np.isfinite(lam)):
        raise ContactError(f"the warm start must be {r} finite values, got shape {lam.shape}")
    lam[problem.slices["effector"]] = 0.0
    previous = np.zeros(len(actuators)) if previous_displacement is None else previous_displacement
    lo, hi, dmin, dmax = actuator_bounds(list(actuators), np.asarray(previous, dtype=float))
    layout = _Blocks(
        np.arange(act.start, act.stop, dtype=np.int64),
        np.array([a.mode == "displacement" for a in actuators], dtype=np.bool_),
        np.array([a.value for a in actuators], dtype=float),
        lo,
        hi,
        dmin,
        dmax,
        contact_rows.start,
        mu,
    )
    # Gauss-Seidel, and after 8 (or r/3, about the cost of the dense solve in sweeps), then
    # twice as many sweeps, ... a jump to the exact solution of the blocks' current states.
    iterations, residual = 0, math.inf
    next_jump = max(8, r // 3)
    while iterations < max_iterations:
        sweeps, residual = kernels.gauss_seidel(
            w,
            d,
            lam,
            *layout.arrays(),
            float(tolerance),
            min(next_jump, max_iterations) - iterations,
        )
        iterations += int(sweeps)
        if residual <= tolerance or iterations >= max_iterations:
            break
        jump = _active_set_solution(w, d, lam, layout, tolerance)
        if jump is not None:
            lam = jump
        next_jump *= 2
    converged = bool(residual <= tolerance)
    if not converged:
        warnings.warn(
            f"the contact solver stopped after {iterations} Gauss-Seidel sweeps with residual"
            f" {residual:.3g} > tolerance {tolerance:.3g}; raise max_iterations, loosen the"
            " tolerance or reduce the time step",
            ContactConvergenceWarning,
            stacklevel=2,
        )
    return ContactSolution(
        lam, w @ lam + d, ContactReport(iterations, float(residual), converged), problem.slices
    )


@dataclass(frozen=True)
class _Blocks:
    """The blocks of a contact problem, in the order the Gauss-Seidel kernel takes them."""

    actuator_rows: np.ndarray
    displacement_mode: np.ndarray
    command: np.ndarray
    force_lo: np.ndarray
    force_hi: np.ndarray
    course_lo: np.ndarray
    course_hi: np.ndarray
    contact_start: int
    friction: np.ndarray

    def arrays(self) -> tuple:
        return tuple(getattr(self, f.name) for f in fields(self))


def _active_set_solution(
    w: np.ndarray, d: np.ndarray, lam: np.ndarray, blocks: _Blocks, tolerance: float
) -> np.ndarray | None:
    """The multipliers that meet exactly the laws of the blocks in their current states, or
    None if they are not admissible.

    States read from lam: a separated contact (lambda_n = 0) keeps lambda = 0; a sticking one
    has its three rows free with delta = 0; a slipping one keeps its friction direction
    d_t = lambda_t / |lambda_t|, lambda_t = mu lambda_n d_t, with delta_n = 0. An actuator
    strictly inside its force bounds and bound to a displacement (its command, or the course
    bound that holds a force command) is free with that delta; the others keep their lambda.
    One least-squares solve on these equations (W may be singular, e.g. coplanar corners of a
    rigid box); the answer is kept if it meets the equations, the signs, cones and bounds, and
    Gauss-Seidel goes on from it (a slip direction may still turn: the sweeps remain the judge
    of convergence). Once Gauss-Seidel has found the states, this ends the slow linear tail of
    its convergence.
    """
    r = d.size
    fixed = lam.copy()
    directions, rows, targets = [], [], []

    def free(direction: dict[int, float], row: int, target: float) -> None:
        column = np.zeros(r)
        for i, value in direction.items():
            column[i] = value
            fixed[i] = 0.0
        directions.append(column)
        rows.append(row)
        targets.append(target)

    b = blocks
    for j, i in enumerate(b.actuator_rows):
        if not b.force_lo[j] < lam[i] < b.force_hi[j]:
            continue
        if b.displacement_mode[j]:
            free({i: 1.0}, i, min(max(b.command[j], b.course_lo[j]), b.course_hi[j]))
            continue
        command = min(max(b.command[j], b.force_lo[j]), b.force_hi[j])
        if lam[i] != command:  # held on a course bound: the upper one lowers the force
            free({i: 1.0}, i, b.course_hi[j] if lam[i] < command else b.course_lo[j])
    mu = b.friction
    normal = b.contact_start + 3 * np.arange(mu.size)
    for k, n in enumerate(normal):
        if lam[n] <= 0.0:
            continue
        tangential = math.hypot(lam[n + 1], lam[n + 2])
        if tangential < mu[k] * lam[n] * (1.0 - 1e-9):
            for row in (n, n + 1, n + 2):
                free({row: 1.0}, row, 0.0)
        else:  # on the rim of the cone (a frictionless contact has lambda_t = 0 there)
            slip = mu[k] / tangential if tangential > 0.0 else 0.0
            free({n: 1.0, n + 1: slip * lam[n + 1], n + 2: slip * lam[n + 2]}, n, 0.0)
    if not rows:
        return None
    basis = np.array(directions).T
    matrix = w[rows] @ basis
    rhs = np.array(targets) - d[rows] - w[rows] @ fixed
    try:
        x = np.linalg.lstsq(matrix, rhs, rcond=1e-12)[0]
    except np.linalg.LinAlgError:
        return None
    if np.abs(matrix @ x - rhs).max() > tolerance:
        return None
    new = fixed + basis @ x
    delta = w @ new + d
    lam_n, delta_n = new[normal], delta[normal]
    tangential = np.hypot(new[normal + 1], new[normal + 2])
    act = b.actuator_rows
    inside = (new[act] > b.force_lo) & (new[act] < b.force_hi) & ~b.displacement_mode
    admissible = (
        np.all(lam_n >= 0.0)
        and np.all(tangential <= mu * lam_n * (1.0 + 1e-12))
        and np.all(delta_n[lam_n == 0.0] >= -tolerance)
        and np.all((new[act] >= b.force_lo) & (new[act] <= b.force_hi))
        and np.all(delta[act][inside] >= b.course_lo[inside] - tolerance)
        and np.all(delta[act][inside] <= b.course_hi[inside] + tolerance)
    )
    return new if admissible else None


def _records(keys: np.ndarray) -> np.ndarray:
    """(k,) rows of int64 keys (k, 3) viewed as single records, to sort and compare."""
    rows = np.ascontiguousarray(keys, dtype=np.int64)
    return rows.view(np.dtype((np.void, rows.itemsize * rows.shape[1]))).ravel()


@dataclass(frozen=True)
class ContactForces:
    """Contact forces of a step in world coordinates, by contact identity: what the next step
    warm-starts from (the tangent frames may turn between steps; world vectors do not).

    Attributes:
        keys: (k, 3) int64 contact identities (ContactSet.keys).
        forces: (k, 3) lambda_n n + lambda_t1 t1 + lambda_t2 t2, the force of side b on
            side a (n points from b to a).
    """

    keys: np.ndarray
    forces: np.ndarray

    @classmethod
    def empty(cls) -> ContactForces:
        return cls(np.zeros((0, 3), dtype=np.int64), np.zeros((0, 3)))

    @classmethod
    def from_multipliers(cls, contacts: ContactSet, multipliers: np.ndarray) -> ContactForces:
        """From the (k, 3) or (3k,) contact multipliers expressed in the contacts' frames."""
        lam = np.asarray(multipliers, dtype=float).reshape(-1, 3)
        return cls(contacts.keys, np.einsum("kr,krj->kj", lam, contacts.frames))

    def warm_start(self, contacts: ContactSet) -> np.ndarray:
        """(3k,) multipliers for `contacts` in their frames: the previous force of the contact
        with the same identity projected on its new frame, zero for a new contact."""
        previous = np.zeros((len(contacts), 3))
        if len(self.keys) and len(contacts):
            # Identities as 24-byte records, matched by a sorted search (the last of equals).
            old, new = _records(self.keys), _records(contacts.keys)
            order = np.argsort(old, kind="stable")
            at = np.searchsorted(old[order], new, side="right") - 1
            found = (at >= 0) & (old[order[at]] == new)
            previous[found] = self.forces[order[at[found]]]
        return np.einsum("krj,kj->kr", contacts.frames, previous).reshape(-1)

    def copy(self) -> ContactForces:
        return ContactForces(self.keys.copy(), self.forces.copy())


class ContactConstraint(Constraint):
    """Contact rows of points of a deformable body against shapes, three per contact.

    The rows are linearised at detection: with p(x) = sum_a w_a x_a the point carried by the
    body, p0 = contacts.point_a + r n its position at detection (r: the points' thickness, the
    radius of the balls they are; point_a is where a ball meets the normal) and u the
    obstacle's displacement over the step,

        delta_n = phi + n . (p(x) - p0 - u),   delta_ti = t_i . (p(x) - p0 - u),

    so delta = (phi, 0, 0) at detection for a still obstacle, and H rows = w_a (n, t1, t2).

    Args:
        contacts: from `detect(points.positions(x), shapes, margin)`; index_a indexes `points`.
        points: the query points embedded in the body (EmbeddedPoints.at_nodes(surface_nodes)
            for nodes, or barycentric points).
        friction: mu per contact (or one for all), e.g. mu_of_shape[contacts.index_b].
        obstacle_displacement: (k, 3) u, e.g. h * shape_velocities(contacts, shapes); default 0.
        thickness: r, the radius the contacts were detected with (`detect(..., radius=r)`).
    """

    role = "contact"

    def __init__(
        self,
        contacts: ContactSet,
        points: EmbeddedPoints,
        *,
        friction: np.ndarray | float = 0.0,
        obstacle_displacement: np.ndarray | None = None,
        thickness: float = 0.0,
        name: str = "contacts",
    ) -> None:
        self.name = name
        self.contacts = contacts
        k = len(contacts)
        if k and (contacts.index_a.min() < 0 or contacts.index_a.max() >= len(points)):
            raise ContactError(f"{name}: contacts index points outside the {len(points)} given")
        self.friction = check_friction(friction, k)
        self.nodes = points.nodes[contacts.index_a]
        self.weights = points.weights[contacts.index_a]
        u = np.zeros((k, 3)) if obstacle_displacement is None else obstacle_displacement
        u = np.asarray(u, dtype=float)
        if u.shape != (k, 3) or not np.all(np.isfinite(u)):
            raise ContactError(f"{name}: obstacle_displacement must be finite ({k}, 3)")
        self._origin = contacts.point_a + thickness * contacts.normal + u
        self._gap = contacts.gap
        self._frames = contacts.frames

    @property
    def n_rows(self) -> int:
        return 3 * len(self.contacts)

    @property
    def frames(self) -> np.ndarray:
        """(k, 3, 3) rows (n, t1, t2) of each contact: H_c = blockdiag(frames) P."""
        return self._frames

    def distance(self, x: np.ndarray) -> np.ndarray:
        p = np.einsum("ka,kai->ki", self.weights, x[self.nodes])
        delta = np.einsum("krj,kj->kr", self._frames, p - self._origin)
        delta[:, 0] += self._gap
        return delta.reshape(-1)

    def jacobian(self, x: np.ndarray) -> JacobianRows:
        k, m = self.nodes.shape
        values = self.weights[:, None, :, None] * self._frames[:, :, None, :]
        nodes = np.repeat(self.nodes[:, None, :], 3, axis=1)
        return JacobianRows(nodes.reshape(3 * k, m), values.reshape(3 * k, m, 3))
