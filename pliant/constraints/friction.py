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

Projected block Gauss-Seidel (Jean, CMAME 177, 1999) gives each block (an actuator row, a
contact triple) in turn the exact solution of its own law with the other multipliers frozen:
for a contact the normal projection max(0, .), then the tangential problem
min 1/2 x^T W_tt x + g^T x on the disk |x| <= mu lambda_n, whose solution satisfies Coulomb's law
exactly even for an anisotropic W_tt (a radial clamp would not). Its fixed points are the
solutions, and the largest change of a block's displacement in a sweep is the residual that
decides convergence. Alone it converges linearly, slowly where rows are strongly coupled: two
fingers squeezing a rigid cube (normal rows correlated at -0.98 through the cube), stiff cables
pressing the body on a contact, a rigid box on its corners (W singular).

The solver is therefore a semismooth Newton method on the Alart-Curnier function F
(:func:`pliant.constraints.contact_kernels.alart_curnier`; Alart and Curnier, CMAME 92, 1991),
whose zeros are the same solutions, with the actuators' laws in the same F. Each iteration
makes one Gauss-Seidel sweep from the iterate, the judge of convergence as before, and one
Newton step: the direction solves (J + eps P) x = -F, P the term of W + eps diag(W) (a proximal
point regularisation, Rockafellar 1976, as in Siconos: W of an indeterminate grasp is singular),
refined once towards J x = -F; Armijo's line search on |F|^2, eps adapted as a
Levenberg-Marquardt parameter in [1e-8, 1e-2]. Where no step decreases |F|, the sweep's result
is the next iterate. Sweeps a step in the bench's timed windows (Gauss-Seidel with the
active-set jump it replaces -> this solver, whose Newton steps are in the report): gripper
635 -> 14 (12 Newton steps; 10 of 20 steps stopped unconverged, now none), Trunk with cables and
cube 173 -> 4, Multigait 76 -> 3, trunk_cube 45 -> 3. Measured on the same windows' problems
and not kept: a proximal-point outer loop with Gauss-Seidel inside (more sweeps than plain
Gauss-Seidel on the gripper: the proximal term that speeds up the inner sweeps slows the outer
loop as much), nonsmooth nonlinear conjugate gradients (Silcowitz, Niebe and Erleben 2010;
gripper 620 -> 587, trunk with cube 173 -> 82), Anderson acceleration of the sweeps (gripper
146, erratic: the extrapolation upsets the contact states; trunk with cube 20).

Where the forces are not unique (a rigid box on its 4 corners), the solution found depends on
the method: along the forces' null space, the proximal term moves this one least from its
warm start.
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
    embedded_rows,
)
from pliant.constraints.condensed import CondensedProblem
from pliant.errors import ContactConvergenceWarning, ContactError
from pliant.fem.material import check_friction
from pliant.geometry.collision import ContactSet


@dataclass(frozen=True)
class ContactReport:
    """How the contact solve ended.

    Attributes:
        iterations: Gauss-Seidel sweeps made (one per iteration, each with a Newton step).
        residual: largest displacement correction of one block in the last sweep (units of
            delta).
        converged: residual <= tolerance.
        newton_steps: Newton steps taken (the other iterations took the sweep's result).
        screened: contacts left out of the solve, at zero force, because they stay open
            without it (:class:`pliant.solvers.ImplicitEuler`'s contact screening).
        rounds: solves of the step (more than one when screening had to take contacts back);
            `iterations` and `newton_steps` count those of every round.
    """

    iterations: int = 0
    residual: float = 0.0
    converged: bool = True
    newton_steps: int = 0
    screened: int = 0
    rounds: int = 1


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
    layout = ContactBlocks.of(actuators, previous, act, contact_rows.start, mu)
    iterations, newton_steps, residual = kernels.newton_gauss_seidel(
        w, d, lam, layout.arrays(), float(tolerance), max_iterations
    )
    report = ContactReport(
        int(iterations), float(residual), bool(residual <= tolerance), int(newton_steps)
    )
    if not report.converged:
        warnings.warn(
            f"the contact solver stopped after {iterations} Gauss-Seidel sweeps with residual"
            f" {residual:.3g} > tolerance {tolerance:.3g}; raise max_iterations, loosen the"
            " tolerance or reduce the time step",
            ContactConvergenceWarning,
            stacklevel=2,
        )
    return ContactSolution(lam, w @ lam + d, report, problem.slices)


@dataclass(frozen=True)
class ContactBlocks:
    """The blocks of a contact problem, in the order the kernels take them."""

    actuator_rows: np.ndarray
    displacement_mode: np.ndarray
    command: np.ndarray
    force_lo: np.ndarray
    force_hi: np.ndarray
    course_lo: np.ndarray
    course_hi: np.ndarray
    contact_start: int
    friction: np.ndarray

    @classmethod
    def of(
        cls,
        actuators: Sequence[Actuator],
        previous_displacement: np.ndarray,
        actuator_rows: slice,
        contact_start: int,
        friction: np.ndarray,
    ) -> ContactBlocks:
        """The actuators' rows, modes, commands and this step's bounds, and the contacts'."""
        lo, hi, dmin, dmax = actuator_bounds(
            list(actuators), np.asarray(previous_displacement, dtype=float)
        )
        return cls(
            np.arange(actuator_rows.start, actuator_rows.stop, dtype=np.int64),
            np.array([a.mode == "displacement" for a in actuators], dtype=np.bool_),
            np.array([a.value for a in actuators], dtype=float),
            lo,
            hi,
            dmin,
            dmax,
            contact_start,
            friction,
        )

    def arrays(self) -> tuple:
        return tuple(getattr(self, f.name) for f in fields(self))


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
    Points that are not linear in the nodes (``points.linear`` False: a surface skinned on a
    rod's frames) give their own rows, `points.rows(x, ...)`, linearised at x.

    Args:
        contacts: from `detect(points.positions(x), shapes, margin)`; index_a indexes `points`.
        points: the query points embedded in the body (EmbeddedPoints.at_nodes(surface_nodes)
            for nodes, or barycentric points).
        friction: mu per contact (or one for all), e.g. mu_of_shape[contacts.index_b].
        obstacle_displacement: (k, 3) u, e.g. h * shape_velocities(contacts, shapes); default 0.
        thickness: r, the radius the contacts were detected with (`detect(..., radius=r)`).
    """

    role = "contact"
    # The rows' dependence on rigid bodies' twists: none here; a
    # :class:`pliant.constraints.contact.CoupledContact` carries the body's rows and its own.
    rigid_jacobian = None

    @property
    def rows(self) -> ContactConstraint:
        """The deformable body's contact rows: all of them."""
        return self

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
        self.points = points
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

    def take(self, index: np.ndarray) -> ContactConstraint:
        """The rows of the contacts `index` (indices or a boolean mask), in that order."""
        out = ContactConstraint.__new__(ContactConstraint)
        out.name = self.name
        out.contacts = self.contacts.take(index)
        out.points = self.points
        out._frames = self._frames[index]
        for name in ("friction", "nodes", "weights", "_origin", "_gap"):
            setattr(out, name, getattr(self, name)[index])
        return out

    def distance(self, x: np.ndarray) -> np.ndarray:
        if self.points.linear:
            p = np.einsum("ka,kai->ki", self.weights, x[self.nodes])
        else:
            p = self.points.positions(x)[self.contacts.index_a]
        delta = np.einsum("krj,kj->kr", self._frames, p - self._origin)
        delta[:, 0] += self._gap
        return delta.reshape(-1)

    def jacobian(self, x: np.ndarray) -> JacobianRows:
        # w_a (n, t1, t2) for embedded points; a skinned point's rows turn with its frames.
        if self.points is _LINEAR:  # rows on their own nodes (relative points)
            return embedded_rows(self.nodes, self.weights, self._frames)
        return self.points.rows(x, self.contacts.index_a, self._frames)

    @classmethod
    def relative(
        cls,
        contacts: ContactSet,
        nodes: np.ndarray,
        weights: np.ndarray,
        origin: np.ndarray,
        *,
        friction: np.ndarray | float = 0.0,
        name: str = "contacts",
    ) -> ContactConstraint:
        """Rows on points given by their own `nodes` and `weights` (k, m), linear in the
        nodes, read from `origin` (k, 3): delta = frames (p(x) - origin) + (gap, 0, 0). The
        relative point of two pieces of a body (:mod:`pliant.constraints.surface`); the
        contacts' index_a identifies them and indexes nothing."""
        out = cls.__new__(cls)
        out.name = name
        out.contacts = contacts
        out.friction = check_friction(friction, len(contacts))
        out.points = _LINEAR
        out.nodes = np.ascontiguousarray(nodes, dtype=np.int64)
        out.weights = np.ascontiguousarray(weights, dtype=float)
        out._origin = np.asarray(origin, dtype=float)
        out._gap = contacts.gap
        out._frames = contacts.frames
        return out

    @classmethod
    def joined(cls, parts: Sequence[ContactConstraint]) -> ContactConstraint:
        """The rows of `parts` in order, as one constraint (points linear in the nodes; those
        read through fewer nodes than the widest get node 0 with weight 0 in the spare
        columns)."""
        width = max(p.nodes.shape[1] for p in parts)
        out = cls.__new__(cls)
        out.name = parts[0].name
        out.contacts = ContactSet.concatenate([p.contacts for p in parts])
        out.points = _LINEAR
        out.nodes = np.vstack(
            [np.pad(p.nodes, ((0, 0), (0, width - p.nodes.shape[1]))) for p in parts]
        )
        out.weights = np.vstack(
            [np.pad(p.weights, ((0, 0), (0, width - p.weights.shape[1]))) for p in parts]
        )
        for name in ("friction", "_origin", "_gap", "_frames"):
            setattr(out, name, np.concatenate([getattr(p, name) for p in parts]))
        return out


class _Linear:
    """The points of rows given by their own nodes and weights: linear in the nodes."""

    linear = True


_LINEAR = _Linear()
