"""The reduced implicit Euler step: the full step of :class:`pliant.solvers.ImplicitEuler`
projected on a basis, its forces integrated over the reduced integration domain.

With q = q0 + Phi alpha and v = Phi u, Galerkin projection of the full step (Eq. 2.2-2.5) gives

    A_r du = b_r + h H_r^T lambda,   A_r = (1 + h a) M_r + (h b + h^2) K_r,
    b_r = h (f_r + Phi^T f_ext) - h a M_r u - (h b + h^2) (K v)_r,

M_r = Phi^T M Phi (exact, kept), f_r = sum_RID xi_e Phi_e^T f_e(q_e), K_r and (K v)_r likewise
(ECSW, :mod:`pliant.reduction.ecsw`), and every constraint row read through the basis,
H_r = H Phi. The constraints (cavities, cables, effectors, floor contacts on the colliding
points) are condensed as in the full step, W = h^2 H_r A_r^-1 H_r^T and
delta_free = delta(q) + h H_r (u + du_free), and solved by the same routines
(:func:`pliant.constraints.control.constraint_forces`: the direct box QP, the
Signorini-Coulomb solver, the inverse QP).

What makes it fast: positions are needed only at the nodes of the selected elements, of the
constraints and of the colliding points (the active nodes), q_a = q0_a + Phi_a alpha; the
other nodes are never computed during a step. A_r is a dense r x r matrix, factorised again
when the selected elements' frames drift past the body's lag tolerance (the full solver's
"lagged" policy) or at every step ("fresh").

The state is a :class:`ReducedState` (alpha, u and the constraint forces); its `positions`
and `velocities` are the full fields q0 + Phi alpha and Phi u, computed when asked (rendering,
observations); :meth:`ReducedImplicitEuler.reduce` projects a full state on the basis.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numba
import numpy as np
import scipy.linalg

from pliant.constraints.cavity import CavityActuator
from pliant.constraints.condensed import CondensedProblem
from pliant.constraints.control import constraint_forces
from pliant.constraints.friction import ContactForces
from pliant.errors import DivergenceError, ReductionError, SolverError
from pliant.fem import kernels as fem_kernels
from pliant.model import Model, State
from pliant.reduction import kernels
from pliant.reduction.basis import ReducedBasis
from pliant.reduction.cavity import reduced_cavity
from pliant.reduction.ecsw import IntegrationDomain
from pliant.solvers.base import StepReport, begin_control


@dataclass
class ReducedState:
    """Reduced coordinates alpha and rates u (q = q0 + Phi alpha, v = Phi u), time, step count
    and the last constraint forces (as :class:`pliant.model.State`).

    `positions` and `velocities` are the full fields, computed from the basis when asked; a
    state unpickled in another process has no basis until
    :meth:`ReducedImplicitEuler.attach` gives it one.
    """

    coordinates: np.ndarray
    rates: np.ndarray
    time: float = 0.0
    step: int = 0
    actuation: np.ndarray = field(default_factory=lambda: np.zeros(0))
    displacement: np.ndarray = field(default_factory=lambda: np.zeros(0))
    contact_forces: ContactForces = field(default_factory=ContactForces.empty)
    basis: ReducedBasis | None = field(default=None, repr=False, compare=False)

    @classmethod
    def of(cls, coordinates, rates, state, basis: ReducedBasis | None) -> ReducedState:
        """Coordinates and rates at the time and step of `state` (full or reduced), with copies
        of its actuation, displacement and contact forces."""
        copies = (state.actuation.copy(), state.displacement.copy(), state.contact_forces.copy())
        return cls(coordinates, rates, state.time, state.step, *copies, basis)

    def copy(self) -> ReducedState:
        return ReducedState.of(self.coordinates.copy(), self.rates.copy(), self, self.basis)

    def __getstate__(self) -> dict:
        # The basis is the solver's (megabytes): a snapshot carries the coordinates only.
        return {**self.__dict__, "basis": None}

    def _basis(self) -> ReducedBasis:
        if self.basis is None:
            raise ReductionError(
                "this reduced state has no basis (unpickled?): give it one with"
                " ReducedImplicitEuler.attach(state)"
            )
        return self.basis

    @property
    def positions(self) -> np.ndarray:
        """q0 + Phi alpha (n, 3)."""
        return self._basis().positions(self.coordinates)

    @property
    def velocities(self) -> np.ndarray:
        """Phi u (n, 3)."""
        return self._basis().modes @ self.rates

    def allclose(self, other: ReducedState, *, atol: float = 0.0) -> bool:
        return (
            self.step == other.step
            and np.allclose(self.coordinates, other.coordinates, rtol=0, atol=atol)
            and np.allclose(self.rates, other.rates, rtol=0, atol=atol)
        )

    def to_full(self) -> State:
        """The full :class:`pliant.model.State` of this reduced one."""
        return State(
            self.positions,
            self.velocities,
            self.time,
            self.step,
            self.actuation.copy(),
            self.displacement.copy(),
            self.contact_forces.copy(),
        )


class _ReducedTangent:
    """A_r = mass_coef M_r + stiffness_coef K_r, factorised (dense Cholesky), kept while the
    selected elements' frames stay within the lag tolerance ("lagged") or never ("fresh")."""

    def __init__(self, policy: str, lag_tolerance: float) -> None:
        if policy not in ("lagged", "fresh"):
            raise SolverError(
                f"the reduced tangent policy must be 'lagged' or 'fresh', got {policy!r}"
            )
        self.policy = policy
        self.lag_tolerance = lag_tolerance
        self.factorisations = 0
        self._factor = None
        self._frames: np.ndarray | None = None

    def invalidate(self) -> None:
        """Forget the factorisation (after a state restore, to stay reproducible)."""
        self._factor = None

    def needs(self, frames: np.ndarray) -> bool:
        return (
            self._factor is None
            or self.policy == "fresh"
            or (frames.size and np.max(np.abs(frames - self._frames)) > self.lag_tolerance)
        )

    def factorise(self, matrix: np.ndarray, frames: np.ndarray) -> None:
        try:
            self._factor = scipy.linalg.cho_factor(matrix, check_finite=True)
        except (np.linalg.LinAlgError, ValueError) as exc:
            raise SolverError(f"the reduced system is not positive definite ({exc})") from exc
        self._frames = frames.copy()
        self.factorisations += 1

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        return scipy.linalg.cho_solve(self._factor, rhs, check_finite=False)


class _Membrane:
    """The selected triangles of a membrane, their weights and the basis on their nodes."""

    def __init__(self, membrane, elements: np.ndarray, weights: np.ndarray, modes: np.ndarray):
        self.mu, self.lam = membrane.mu, membrane.lam
        self.triangles = np.ascontiguousarray(membrane.triangles[elements])
        self.grads = np.ascontiguousarray(membrane.grads[elements])
        self.areas = np.ascontiguousarray(membrane.areas[elements])
        t, r = len(elements), modes.shape[2]
        self.phi = np.ascontiguousarray(modes[self.triangles].reshape(t, 9, r))
        self.weighted = (weights[:, None, None] * self.phi).reshape(9 * t, r)
        self.forces, self.tangents = np.empty((t, 9)), np.empty((t, 9, 9))

    def evaluate(self, x: np.ndarray, v: np.ndarray) -> np.ndarray:
        """(9 t, 2): the triangles' forces and K v (compiled kernel)."""
        kernels.membrane_forces_tangent(
            x, self.triangles, self.grads, self.areas, self.mu, self.lam, self.forces, self.tangents
        )
        local = v[self.triangles].reshape(-1, 9)
        kv = np.einsum("trc,tc->tr", self.tangents, local)
        return np.stack([self.forces.reshape(-1), kv.reshape(-1)], axis=1)


class ReducedImplicitEuler:
    """Dynamic solver of a model reduced on a basis, with the step interface of
    :class:`pliant.solvers.ImplicitEuler` (module docstring).

    Args:
        model: the full model (its body, actuators, effectors and contacts).
        basis: the reduced basis (:func:`pliant.reduction.pod`).
        domain: the reduced integration domain (:func:`pliant.reduction.hyper_reduce`);
            None: every element with weight 1 (exact reduced forces).
        dt: time step h.
        tangent: "lagged" (the full solver's default policy, on the selected elements) or
            "fresh" (A_r rebuilt at every step).
        lag_tolerance: largest change of a selected element's frame entry before the lagged
            tangent is rebuilt (default: the body's, as the full solver).
        contact_compliance: added to the diagonal of W on the contact rows, relative to their
            mean: a contact then gives way by that fraction of its own response. Through r
            modes, W has rank r at most on 3 rows per colliding point (31 modes, 369 rows on
            the reference Multigait): the contact forces are indeterminate and the contact
            solver can stall (6 of the gait's 360 steps at 1000 sweeps there). 1e-4 removed
            every stall and moved the gait's travel by 0.15 mm (-5.42 to -5.27 mm, the full
            FEM's -5.25); default 0, the full step's contact law.
    """

    def __init__(
        self,
        model: Model,
        basis: ReducedBasis,
        domain: IntegrationDomain | None = None,
        dt: float = 0.01,
        *,
        tangent: str = "lagged",
        lag_tolerance: float | None = None,
        contact_compliance: float = 0.0,
    ) -> None:
        if not (np.isfinite(dt) and dt > 0):
            raise SolverError(f"the time step must be finite and > 0, got {dt!r}")
        if not (np.isfinite(contact_compliance) and contact_compliance >= 0):
            raise SolverError(
                f"the contact compliance must be finite and >= 0, got {contact_compliance!r}"
            )
        if model.drivers or model.rigid_bodies or model.attachments:
            raise ReductionError(
                f"{model.name}: the reduced solver handles a body with actuators, effectors"
                " and obstacles; driven nodes, rigid bodies and attachments are not reduced"
            )
        body = model.body
        basis.check(body)
        domain = IntegrationDomain.everything(body) if domain is None else domain
        if len(domain.membranes) != len(body.membranes):
            raise ReductionError(
                f"the integration domain has {len(domain.membranes)} membrane selections, the"
                f" body {len(body.membranes)} membranes"
            )
        self.model, self.basis, self.domain, self.dt = model, basis, domain, float(dt)
        modes, r = basis.modes, basis.n_modes
        flat = modes.reshape(-1, r)
        self.mass = flat[body.free_dofs].T @ body.mass_matvec(flat[body.free_dofs])
        self.gravity = flat.T @ body.gravity_forces().reshape(-1)
        self.system = _ReducedTangent(
            tangent, body.lag_tolerance if lag_tolerance is None else float(lag_tolerance)
        )
        # The selected tetrahedra, with their arrays and the basis on their nodes.
        e, w = domain.tets.elements, domain.tets.weights
        self._tets = np.ascontiguousarray(body.tets[e])
        self._grads = np.ascontiguousarray(body.grads[e])
        self._volumes = np.ascontiguousarray(body.volumes[e])
        self._mu, self._lam = np.ascontiguousarray(body.mu[e]), np.ascontiguousarray(body.lam[e])
        # What the element kernels read of the selected elements, material tag included.
        self._domain = (
            self._tets,
            self._grads,
            self._volumes,
            self._mu,
            self._lam,
            body.material.kernel_tag,
        )
        # SOFA's "large" frames (empty for the polar rotation) of the selected elements.
        large = body.frame_nodes.shape[0] > 0
        self._frame_nodes = np.ascontiguousarray(body.frame_nodes[e] if large else body.frame_nodes)
        self._rest_frames = np.ascontiguousarray(body.rest_frames[e] if large else body.rest_frames)
        m = e.size
        self._phi = np.ascontiguousarray(modes[self._tets].reshape(m, 12, r))
        self._weighted = (w[:, None, None] * self._phi).reshape(12 * m, r)
        self._elem = np.empty((m, 4, 6))
        self._frames, self._dets = np.empty((m, 3, 3)), np.empty(m)
        self._blocks = np.empty((m, 12, 12))
        self._membranes = [
            _Membrane(a.membrane, s.elements, s.weights, modes)
            for a, s in zip(body.membranes, domain.membranes, strict=True)
        ]
        # The active nodes: those of the selected elements, of the constraints and of the
        # colliding points; positions are computed there only.
        rest = body.rest_positions
        wanted = [self._tets.reshape(-1)] + [s.triangles.reshape(-1) for s in self._membranes]
        # Cavities from their walls or as exact polynomials of alpha, whichever is cheaper
        # (pliant.reduction.cavity); a polynomial's walls need no positions.
        self._cavities = {
            id(c): reduced_cavity(c, rest, modes)
            for c in model.constraints
            if isinstance(c, CavityActuator)
        }
        wanted += [c.nodes for c in self._cavities.values()]
        wanted += [
            c.jacobian(rest).nodes.reshape(-1)
            for c in model.constraints
            if id(c) not in self._cavities
        ]
        if model.contacts is not None:
            wanted.append(model.contacts.points.nodes.reshape(-1))
            for surface in model.contacts.surfaces:  # the points and the surface they touch
                wanted += [surface.points.nodes.reshape(-1), surface.vertices.nodes.reshape(-1)]
        self.active = np.unique(np.concatenate(wanted)) if wanted else np.zeros(0, np.int64)
        self._active_modes = np.ascontiguousarray(modes[self.active].reshape(-1, r))
        self._active_rest = rest[self.active]
        self._x, self._v = rest.copy(), np.zeros_like(rest)
        self._placed: np.ndarray | None = None  # the coordinates self._x holds
        self._size = body.extent
        self.contact_compliance = float(contact_compliance)
        self.last_report = StepReport()

    # ------------------------------------------------------------------------ states
    @property
    def n_modes(self) -> int:
        return self.basis.n_modes

    def rest_state(self) -> ReducedState:
        """alpha = 0 (the rest shape), at rest."""
        r, a = self.basis.n_modes, self.model.n_actuators
        return ReducedState(
            np.zeros(r), np.zeros(r), 0.0, 0, np.zeros(a), np.zeros(a), basis=self.basis
        )

    def reduce(self, state: State) -> ReducedState:
        """The projection of a full state on the basis (orthogonal: alpha = Phi^T (q - q0))."""
        flat = self.basis.modes.reshape(-1, self.basis.n_modes)
        rates = flat.T @ state.velocities.reshape(-1)
        return ReducedState.of(self.basis.coordinates(state.positions), rates, state, self.basis)

    def attach(self, state: ReducedState) -> ReducedState:
        """The state with this solver's basis (after unpickling)."""
        if state.coordinates.shape != (self.basis.n_modes,):
            raise ReductionError(
                f"the state has {state.coordinates.size} coordinates, the basis"
                f" {self.basis.n_modes} modes"
            )
        state.basis = self.basis
        return state

    def _place(self, coordinates: np.ndarray) -> np.ndarray:
        """The work positions with the active nodes at q0 + Phi alpha (kept while alpha is the
        same: a step places its end, the next one its start, at the same coordinates)."""
        if self._placed is None or not np.array_equal(coordinates, self._placed):
            self._x[self.active] = self._active_rest + (self._active_modes @ coordinates).reshape(
                -1, 3
            )
            self._placed = np.array(coordinates, dtype=float)
        return self._x

    def _move(self, rates: np.ndarray) -> np.ndarray:
        self._v[self.active] = (self._active_modes @ rates).reshape(-1, 3)
        return self._v

    # -------------------------------------------------------------------------- step
    def step(self, state: ReducedState | State, control=None) -> ReducedState:
        """Advance one step; `control`: None, actuator commands, DirectControl or
        InverseControl (as :meth:`pliant.solvers.ImplicitEuler.step`). A full State is
        projected on the basis first."""
        if isinstance(state, State):
            state = self.reduce(state)
        saved = numba.get_num_threads()
        numba.set_num_threads(1)  # a few hundred elements: waking threads costs more
        try:
            return self._step(state, control)
        finally:
            numba.set_num_threads(saved)

    def internal_forces(self, coordinates: np.ndarray) -> np.ndarray:
        """f_r(alpha) = sum_RID xi_e Phi_e^T f_e(q0 + Phi alpha) (r,)."""
        x = self._place(np.asarray(coordinates, dtype=float))
        return self._element_forces(x, np.zeros_like(x), 0)[0]

    def stiffness(self, coordinates: np.ndarray) -> np.ndarray:
        """K_r(alpha) = -d f_r / d alpha (r, r), the tangent the step factorises."""
        x = self._place(np.asarray(coordinates, dtype=float))
        _, _, membrane_tangents = self._element_forces(x, np.zeros_like(x), 0)
        return self._tangent(x, membrane_tangents)

    def _coefficients(self) -> tuple[float, float]:
        b, h = self.model.body, self.dt
        alpha, beta = b.uniform_rayleigh("the reduced-order solver (pliant.reduction)")
        return 1.0 + h * alpha, h * beta + h * h

    def _step(self, state: ReducedState, control) -> ReducedState:
        model, h = self.model, self.dt
        ctrl = begin_control(model, state, control)
        step = state.step + 1
        alpha, u = state.coordinates, state.rates
        x, v = self._place(alpha), self._move(u)
        forces, kv, membrane_tangents = self._element_forces(x, v, step)
        a_m, a_k = self._coefficients()
        if self.system.needs(self._frames):
            tangent = self._tangent(x, membrane_tangents)
            try:
                self.system.factorise(a_m * self.mass + a_k * tangent, self._frames)
            except SolverError as exc:
                raise DivergenceError(f"step {step}: {exc}", step=step, cause="solver") from exc
        rhs = h * (forces + self.gravity) - a_k * kv
        if a_m != 1.0:
            rhs -= (a_m - 1.0) * (self.mass @ u)
        du_free = self.system.solve(rhs)
        roles = getattr(ctrl, "roles", None)
        contact = model.contacts.constraint(x, h) if model.contacts is not None else None
        distance, rows, slices = self._rows(alpha, x, roles, contact)
        columns = self.system.solve(rows.T)
        w = h * h * (rows @ columns)
        w = 0.5 * (w + w.T)
        contact_rows = slices["contact"]
        if self.contact_compliance and contact_rows.stop > contact_rows.start:
            diagonal = np.arange(contact_rows.start, contact_rows.stop)
            w[diagonal, diagonal] += self.contact_compliance * np.mean(w[diagonal, diagonal])
        problem = CondensedProblem(w, distance + h * (rows @ (u + du_free)), slices)
        try:
            lam, contact_report, contact_forces = constraint_forces(
                ctrl, problem, model, state, contact
            )
        except SolverError as exc:
            raise DivergenceError(f"step {step}: {exc}", step=step, cause="solver") from exc
        u_new = u + du_free + h * (columns @ lam)
        alpha_new = alpha + h * u_new
        moved = self._active_modes @ (alpha_new - alpha)
        if not (np.all(np.isfinite(alpha_new)) and np.all(np.isfinite(u_new))):
            raise DivergenceError(
                f"step {step}: the reduced state became non-finite; reduce the time step",
                step=step,
                cause="non-finite",
            )
        if moved.size and np.max(np.abs(moved)) > self._size:
            raise DivergenceError(
                f"step {step}: a node moved more than the body's size in one step: energy"
                " blow-up; reduce the time step",
                step=step,
                cause="energy",
            )
        lam_a = lam[problem.slices["actuator"]]
        new = ReducedState(
            alpha_new,
            u_new,
            state.time + h,
            step,
            lam_a,
            self._actuator_distances(alpha_new),
            contact_forces,
            self.basis,
        )
        self.last_report = StepReport(
            problem, lam_a, 0, self.system.factorisations, contact=contact_report
        )
        return new

    def _element_forces(self, x: np.ndarray, v: np.ndarray, step: int):
        """f_r and (K v)_r over the reduced integration domain, and the membranes' tangents."""
        m = self._tets.shape[0]
        fem_kernels.internal_forces(
            x,
            v,
            *self._domain,
            self._frame_nodes,
            self._rest_frames,
            self._elem[:, :, :3],
            self._elem[:, :, 3:],
            self._frames,
            self._dets,
        )
        if m and not self._dets.min() > 0.0:
            bad = int(np.count_nonzero(~(self._dets > 0.0)))
            raise DivergenceError(
                f"step {step}: {bad} selected element(s) inverted; reduce the time step or the"
                " actuation rate, or add modes",
                step=step,
                cause="inverted",
            )
        both = (
            self._weighted.T
            @ self._elem.reshape(m, 4, 2, 3).transpose(0, 1, 3, 2).reshape(12 * m, 2)
            if m
            else np.zeros((self.basis.n_modes, 2))
        )
        tangents = []
        for part in self._membranes:
            both += part.weighted.T @ part.evaluate(x, v)
            tangents.append(part.tangents)
        if not np.all(np.isfinite(both)):
            raise DivergenceError(
                f"step {step}: non-finite internal forces; reduce the time step",
                step=step,
                cause="non-finite",
            )
        return both[:, 0], both[:, 1], tangents

    def _tangent(self, x: np.ndarray, membrane_tangents: list[np.ndarray]) -> np.ndarray:
        """K_r = sum_RID xi_e Phi_e^T K_e Phi_e."""
        m, r = self._tets.shape[0], self.basis.n_modes
        out = np.zeros((r, r))
        if m:
            fem_kernels.element_stiffness(
                x, *self._domain, self._frames, self._dets, False, self._blocks
            )
            out += self._weighted.T @ np.matmul(self._blocks, self._phi).reshape(12 * m, r)
        for part, tangent in zip(self._membranes, membrane_tangents, strict=True):
            out += part.weighted.T @ np.matmul(tangent, part.phi).reshape(-1, r)
        return 0.5 * (out + out.T)

    def _actuator_distances(self, coordinates: np.ndarray) -> np.ndarray:
        """delta of every actuator row at q0 + Phi alpha."""
        out, x = [], None
        for c in self.model.actuators:
            cavity = self._cavities.get(id(c))
            if x is None and (cavity is None or cavity.nodes.size):
                x = self._place(coordinates)
            if cavity is not None:
                change = cavity.change(coordinates, x)
                out.append([change + cavity.rest_volume - c.rest_volume])
            else:
                out.append(c.distance(x))
        return np.concatenate(out) if out else np.zeros(0)

    def _rows(self, coordinates: np.ndarray, x: np.ndarray, roles, contact):
        """delta, H_r = H Phi (rows, r) and the slices of the step's constraint rows at alpha
        (x: the active nodes placed there), in the full step's order: actuators, effectors
        (those of `roles`), contacts."""
        cons = [c for c in self.model.constraints if roles is None or c.role in roles]
        if contact is not None:
            cons.append(contact)
        modes, r = self.basis.modes, self.basis.n_modes
        distances, blocks, slices, start = [], [], {}, 0
        for c in cons:
            cavity = self._cavities.get(id(c))
            if cavity is not None:
                change, gradient = cavity.change_and_gradient(coordinates, x)
                delta = np.array([change + cavity.rest_volume - c.rest_volume])
                block = gradient[None, :]
            else:
                delta, jac = c.distance_and_jacobian(x)
                block = np.einsum("rki,rkis->rs", jac.values, modes[jac.nodes])
            distances.append(delta)
            blocks.append(block)
            stop = start + c.n_rows
            role = slices.get(c.role)
            slices[c.role] = slice(start if role is None else role.start, stop)
            start = stop
        for role in ("actuator", "effector", "contact"):
            slices.setdefault(role, slice(start, start))
        if not cons:
            return np.zeros(0), np.zeros((0, r)), slices
        return np.concatenate(distances), np.vstack(blocks), slices
