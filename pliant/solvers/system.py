"""The linearised system A = a M + c K_s of a step, and when to refactorise it.

Three policies:

* ``"fresh"``: assemble and factorise at every linearisation (what SOFA's SparseLDL does);
* ``"pcg"``: solve the *current* system exactly (to ``rtol``) by conjugate gradients
  preconditioned with the last factorisation; refactorise when CG needs more than
  ``refactor_iterations`` iterations. Same result as "fresh" to the tolerance, far fewer
  factorisations while rotations change slowly;
* ``"lagged"`` (default): use the last factorisation as the system itself (a lagged tangent,
  first-order accurate like the linearisation it replaces; forces are always exact);
  refactorise when an element frame (rotation, or F^-1) has moved by more than
  ``lag_tolerance`` (max entry change) since. Fastest; not identical to "fresh": on the
  Diamond pulled by 4 cables (16 mm motion, 100 steps) the trajectories differ by at most
  8e-3 mm during the transient and 5e-5 mm at the end (measured; see the tests and bench).
  A step that solves no constraint columns (``prepare(..., warp=True)``: a body swinging
  free) first tries to turn the kept factorisation by the nodes' best-fit rotations
  (:meth:`LinearisedSystem._turn`) and refactorises only where that does not explain every
  element's turn to ``lag_tolerance``: the free-swinging Diamond and Trunk of ``pliant
  bench`` refactorise at 0.39 and 0.72 of their steps instead of 0.57 and 0.97.

The static solver uses "fresh" by default: its Newton iterations then converge quadratically.

A body with nodes held on lines or planes (``TetBody(projections=...)``) has its system
projected: A is replaced by P A P + s (I - P) and each solve by P A^-1 P
(:mod:`pliant.fem.supports`), so every increment, and every column of the constraints'
compliance, moves those nodes only along their lines and planes.

A factorisation may run in the background (``prepare(..., background=True)``): CHOLMOD
releases the GIL, so on a small body (one compiled thread) the step detects its contacts and
builds its constraint rows on the other core meanwhile; the first solve waits for it.
"""

from __future__ import annotations

import os
from concurrent.futures import Future, ThreadPoolExecutor
from functools import cache
from typing import Literal

import numpy as np
import scipy.sparse as sp

from pliant.errors import ModelError, SolverError
from pliant.fem.body import Linearisation, TetBody
from pliant.fem.kernels import max_abs_difference
from pliant.fem.material import COROTATIONAL, COROTATIONAL_LARGE, COROTATIONAL_LARGE_INVERTIBLE
from pliant.fem.rod import RodBody
from pliant.fem.sparsity import StiffnessPattern
from pliant.solvers.linear import SparseCholesky, block_pcg, sparse_cholesky

TangentPolicy = Literal["fresh", "pcg", "lagged"]
#: Material tags whose element frames are rotations (a kept factorisation can be turned).
ROTATION_TAGS = (COROTATIONAL, COROTATIONAL_LARGE, COROTATIONAL_LARGE_INVERTIBLE)


@cache
def _worker() -> ThreadPoolExecutor:
    """The one thread that background factorisations run on."""
    return ThreadPoolExecutor(max_workers=1, thread_name_prefix="pliant-factorise")


# A forked child inherits the executor but not its thread: it starts its own. (A child forked
# after numba's OpenMP kernels ran is stopped by GNU OpenMP itself: use "spawn" or
# "forkserver" for worker processes, as pliant.condensed.collect does.)
os.register_at_fork(after_in_child=_worker.cache_clear)


class LinearisedSystem:
    def __init__(
        self,
        body: TetBody | RodBody,
        *,
        policy: TangentPolicy = "lagged",
        rtol: float = 1e-10,
        refactor_iterations: int = 6,
        lag_tolerance: float | None = None,
        max_iterations: int = 200,
        extra_pattern: tuple[np.ndarray, np.ndarray] | None = None,
        exact_tangent: bool = False,
    ) -> None:
        """`extra_pattern`: free-DoF (rows, cols) of further entries added to A at each
        factorisation (:meth:`prepare`'s `extra` values, one per pair; duplicates add up), e.g.
        the cables' geometric stiffness; the pattern must be symmetric.
        `lag_tolerance`: the "lagged" policy's largest frame change before refactorising
        (default: the body's `lag_tolerance`).
        `exact_tangent`: factorise the exact material tangent (the corotational one with the
        variation of the rotation) rather than SOFA's; where that matrix is not positive
        definite, the factorisation falls back to SOFA's tangent (`last_fallback`)."""
        if policy not in ("fresh", "pcg", "lagged"):
            raise SolverError(f"tangent policy must be 'fresh', 'pcg' or 'lagged', got {policy!r}")
        self.body = body
        self.policy = policy
        self.rtol = rtol
        self.refactor_iterations = refactor_iterations
        self.lag_tolerance = body.lag_tolerance if lag_tolerance is None else lag_tolerance
        self.max_iterations = max_iterations
        self._cholesky: SparseCholesky | None = None
        self._factor_valid = False
        self._factor_frames: np.ndarray | None = None
        self._factor_coefs: tuple[float, float] | None = None
        self._fresh = False
        self._refactor_next = False
        self.factorisations = 0
        self.last_iterations = 0
        self.extra = None
        self.exact_tangent = exact_tangent
        self.last_fallback = False
        self._extra_pattern = extra_pattern
        self._merged = None if extra_pattern is None else _merge(body.pattern, *extra_pattern)
        self._pending: Future | None = None  # a background factorisation
        self._projection = getattr(body, "projection", None)
        self._shift = 1.0  # s of P A P + s (I - P)
        self.warps = 0  # steps solved with the kept factorisation turned
        # Corotational tetrahedral bodies without projections, whose nodes are free or held in
        # all three directions, can turn their kept factorisation: the free nodes
        # (`_warp_nodes`, their DoFs `_warp_dofs`) by their best-fit rotations. (The kernels
        # read four nodes an element: a subclass with other elements keeps the plain policy.)
        self._warp_nodes = self._warp_dofs = self._turns = None
        if (
            type(body) is TetBody
            and body.material.kernel_tag in ROTATION_TAGS
            and self._projection is None
            and body.mass_type != "consistent"
        ):
            free = body.free_index.reshape(-1, 3) >= 0
            self._warp_nodes = np.flatnonzero(np.all(free, axis=1))
            self._warp_dofs = body.free_index.reshape(-1, 3)[self._warp_nodes]
            self._warp_all = np.all(free, axis=1)
            if np.any(np.any(free, axis=1) & ~self._warp_all):
                # A node with one or two free DoFs is not turned: no turn is checked either.
                self._warp_nodes = self._warp_dofs = None

    def invalidate(self) -> None:
        """Forget the factorisation (after a state restore, to stay reproducible)."""
        self._wait()
        self._factor_valid = False

    def prepare(
        self,
        lin: Linearisation,
        mass_coef: float,
        stiffness_coef: float,
        extra: np.ndarray | None = None,
        *,
        background: bool = False,
        warp: bool = False,
    ) -> None:
        """Set the linearisation of the next solves: A = mass_coef M + stiffness_coef K_s
        (+ the `extra` entries on the extra pattern, scaled by stiffness_coef). With
        `background`, a refactorisation runs on another thread until the first solve. With
        `warp` ("lagged" policy), a kept factorisation whose frames moved past
        `lag_tolerance` is turned by the nodes' rotations rather than refactorised where
        that explains every element's turn to `lag_tolerance` (:meth:`_turn`); only for a
        step whose solves all come after this call and none is kept beyond it (a kept
        compliance column would not be turned)."""
        if (extra is None) != (self._merged is None):
            raise SolverError("extra entries need the extra pattern given to the system, and back")
        self.extra = extra
        self.lin = lin
        self.mass_coef = mass_coef
        self.stiffness_coef = stiffness_coef
        self._fresh = False
        self._turns = None
        needs = (
            not self._factor_valid
            or self.policy == "fresh"
            or self._refactor_next
            or not _same_coefficients(self._factor_coefs, (mass_coef, stiffness_coef))
        )
        if not needs and self.policy == "lagged":
            drift = max_abs_difference(lin.frames, self._factor_frames)
            needs = not drift <= self.lag_tolerance  # NaN frames refactorise (and fail there)
            if needs and warp and self._warp_nodes is not None and drift == drift:
                needs = not self._turn(lin)
        if needs:
            self.refactorise(background=background)

    def hand_over(self, replacement: SparseCholesky | None = None) -> SparseCholesky | None:
        """The current factorisation, detached from the system so that it stays valid for
        solves (an adjoint reuses a step's: :mod:`pliant.diff.rollout`); the next one is
        factorised into `replacement` (an earlier one handed over, of the same pattern: no
        new symbolic analysis) or a new one."""
        self._wait()
        factor, self._cholesky = self._cholesky, replacement
        self._factor_valid = False
        return factor

    def refactorise(self, *, background: bool = False) -> None:
        self._wait()
        self._factor_valid = False
        self.last_fallback = False
        if self.exact_tangent:
            try:
                self._factorise(self._assemble(exact=True))
            except SolverError:
                self.last_fallback = True
        if not self.exact_tangent or self.last_fallback:
            data = self._assemble(exact=False)
            if background and not self.last_fallback:
                self._pending = _worker().submit(self._factorise, data)
            else:
                self._factorise(data)
        self._factor_valid = True
        self._factor_frames = self.lin.frames.copy()
        self._factor_coefs = (self.mass_coef, self.stiffness_coef)
        self._fresh = True
        self._refactor_next = False
        self.factorisations += 1

    def _assemble(self, *, exact: bool) -> np.ndarray:
        """Values of A on the system's pattern (the body's, merged with the extra one)."""
        body = self.body
        mass_coef, stiffness_coef = self.mass_coef, self.stiffness_coef
        if np.ndim(stiffness_coef):  # one value a free DoF: per entry, that of its row
            pattern = body.pattern
            rows = np.repeat(np.arange(body.n_free), np.diff(pattern.indptr))
            mass_coef, stiffness_coef = mass_coef[rows], stiffness_coef[rows]
        data = stiffness_coef * body.stiffness_data(self.lin, exact=exact)
        data += mass_coef * body.mass_data
        if self._merged is not None:
            _, indices, body_slots, extra_slots = self._merged
            merged = np.zeros(indices.size)
            merged[body_slots] = data
            extra = self.extra
            if np.ndim(self.stiffness_coef):
                rows, cols = self._extra_pattern
                if np.any(self.stiffness_coef[rows] != self.stiffness_coef[cols]):
                    raise ModelError(
                        "extra entries (a cable's stiffness) join bodies of different"
                        " Rayleigh damping"
                    )
                extra = extra * self.stiffness_coef[rows]
                merged += np.bincount(extra_slots, weights=extra, minlength=indices.size)
            else:
                merged += self.stiffness_coef * np.bincount(
                    extra_slots, weights=extra, minlength=indices.size
                )
            data = merged
        return data if self._projection is None else self._project(data)

    def _pattern_arrays(self) -> tuple[np.ndarray, np.ndarray]:
        pattern = self.body.pattern
        return (pattern.indptr, pattern.indices) if self._merged is None else self._merged[:2]

    def _project(self, data: np.ndarray) -> np.ndarray:
        """P A P + s (I - P) on A's own pattern (P is block-diagonal by node, so the product
        stays in it), with s the mean magnitude of A's diagonal."""
        indptr, indices = self._pattern_arrays()
        n, p = self.body.n_free, self._projection
        a = sp.csr_matrix((data, indices, indptr), shape=(n, n))
        self._shift = float(np.mean(np.abs(a.diagonal()))) or 1.0
        projected = (p @ a @ p + self._shift * (sp.identity(n, format="csr") - p)).tocoo()
        rows = np.repeat(np.arange(n), np.diff(indptr)).astype(np.int64)
        keys = rows * n + indices
        wanted = projected.row.astype(np.int64) * n + projected.col
        slots = np.searchsorted(keys, wanted)
        inside = slots < keys.size
        inside[inside] = keys[slots[inside]] == wanted[inside]
        if not np.all(inside | (projected.data == 0.0)):
            raise SolverError("the projected system left its sparsity pattern")
        return np.bincount(slots[inside], weights=projected.data[inside], minlength=keys.size)

    def _wait(self) -> None:
        """Finish a background factorisation, raising its error here."""
        pending, self._pending = self._pending, None
        if pending is not None:
            try:
                pending.result()
            except BaseException:
                self._factor_valid = False
                raise

    def _factorise(self, data: np.ndarray) -> None:
        if self._cholesky is None:
            self._cholesky = sparse_cholesky(*self._pattern_arrays())
        self._cholesky.factorize(data)

    def apply(self, u: np.ndarray) -> np.ndarray:
        """A u with the current tangent (matrix-free; projected where the body has lines and
        planes)."""
        if self._projection is None:
            return self._apply(u)
        p = self._projection
        pu = p @ u
        return p @ self._apply(pu) + self._shift * (u - pu)

    def _apply(self, u: np.ndarray) -> np.ndarray:
        exact = self.exact_tangent and not self.last_fallback
        # Per-DoF coefficients scale rows (u may hold columns: (n_free, k)).
        mass_coef, stiffness_coef = (
            (c[:, None] if np.ndim(c) and u.ndim == 2 else c)
            for c in (self.mass_coef, self.stiffness_coef)
        )
        out = stiffness_coef * self.body.stiffness_matvec(self.lin, u, exact=exact)
        if self._merged is not None:
            rows, cols = self._extra_pattern
            n = self.body.n_free
            extra = sp.csr_matrix((self.extra, (rows, cols)), shape=(n, n))
            out += stiffness_coef * (extra @ u)
        if np.any(self.mass_coef):
            out += mass_coef * self.body.mass_matvec(u)
        return out

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        """A^-1 rhs for rhs (n_free,) or (n_free, k); P A^-1 P rhs where the body has nodes
        on lines and planes."""
        if self._projection is None:
            return self._solve(rhs)
        p = self._projection
        return p @ self._solve(p @ rhs)

    def _solve(self, rhs: np.ndarray) -> np.ndarray:
        self._wait()
        if self._fresh or self.policy == "lagged":
            self.last_iterations = 0
            return self._warped_solve(rhs)
        cols = rhs[:, None] if rhs.ndim == 1 else rhs
        x, report = block_pcg(
            self.apply,
            self._cholesky.solve,
            cols,
            rtol=self.rtol,
            max_iterations=self.refactor_iterations * 4,
        )
        self.last_iterations = report.iterations
        if not report.converged:
            self.refactorise()
            x = self._cholesky.solve(cols)
        elif report.iterations > self.refactor_iterations:
            self._refactor_next = True
        if not np.all(np.isfinite(x)):
            raise SolverError("the linear solve produced non-finite values")
        return x[:, 0] if rhs.ndim == 1 else x

    def _turn(self, lin: Linearisation) -> bool:
        """Turn the kept factorisation A_f by the nodes' best-fit rotations Q since it was
        made (A^-1 read as Q A_f^-1 Q^T) when Q explains every element's turn R R_f^T to
        `lag_tolerance` (max entry): the turned matrix Q A_f Q^T then has element blocks
        within that of the current ones, as the lagged one has where its frames are within
        it of the current ones. Exact for a body turned rigidly (a lumped or uniform mass is
        unchanged by Q); a free-swinging body turns its elements far more than it strains
        them. Returns whether it did."""
        turns, drift = self.body.node_rotations(lin.frames, self._factor_frames, self._warp_all)
        if not drift <= self.lag_tolerance:
            return False
        self._turns = turns[self._warp_nodes]
        self.warps += 1
        return True

    def _warped_solve(self, r: np.ndarray) -> np.ndarray:
        """A_f^-1 r, or Q A_f^-1 Q^T r where the kept factorisation is turned (:meth:`_turn`)."""
        if self._turns is None:
            return self._cholesky.solve(r)
        idx, q = self._warp_dofs, self._turns
        y = r.copy()
        y[idx] = np.einsum("nji,nj...->ni...", q, r[idx])
        z = self._cholesky.solve(y)
        z[idx] = np.einsum("nij,nj...->ni...", q, z[idx])
        return z


def _same_coefficients(kept, new) -> bool:
    """Whether a factorisation made with coefficients `kept` (None: none made) is one of `new`
    (floats, or per-DoF arrays: the same arrays)."""
    if kept is None:
        return False
    if np.ndim(new[1]) or np.ndim(kept[1]):
        return kept[0] is new[0] and kept[1] is new[1]
    return kept == new


def _merge(pattern: StiffnessPattern, rows: np.ndarray, cols: np.ndarray):
    """The union of a stiffness pattern and extra (row, col) entries: the merged CSR pattern
    (indptr, indices) and the slot of each of the pattern's entries and of each extra entry."""
    n = pattern.n_free
    body_rows = np.repeat(np.arange(n), np.diff(pattern.indptr))
    body_keys = body_rows.astype(np.int64) * n + pattern.indices
    extra_keys = np.asarray(rows, dtype=np.int64) * n + np.asarray(cols, dtype=np.int64)
    keys = np.union1d(body_keys, extra_keys)
    indptr = np.zeros(n + 1, dtype=np.int32)
    np.add.at(indptr, keys // n + 1, 1)
    np.cumsum(indptr, out=indptr)
    indices = (keys % n).astype(np.int32)
    return indptr, indices, np.searchsorted(keys, body_keys), np.searchsorted(keys, extra_keys)
