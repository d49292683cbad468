"""Sparse linear algebra: the Cholesky backend and the preconditioned block CG.

Backend choice (measured on the Diamond's A = M + h^2 K, 4812 DoFs, 145k non-zeros, this
2-core machine): CHOLMOD through ``cholespy`` factorises in 16 ms and solves 1 / 5 right-hand
sides in 0.21 / 0.53 ms; SuperLU (scipy) 33 ms and 0.70 ms per RHS; PARDISO (pypardiso)
180 ms and 1.05 ms. CHOLMOD it is.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from cholespy import CholeskySolverD, MatrixType

from pliant.errors import SolverError


class CholeskyFactor:
    """Sparse Cholesky factor of a symmetric positive definite matrix (CHOLMOD)."""

    def __init__(self, matrix: sp.csr_matrix) -> None:
        if matrix.shape[0] == 0:
            raise SolverError("cannot factorise an empty system: every degree of freedom is fixed")
        csr = sp.csr_matrix(matrix)
        if not np.all(np.isfinite(csr.data)):
            raise SolverError("the system matrix has non-finite entries")
        try:
            self._solver = CholeskySolverD(
                csr.shape[0],
                csr.indptr.astype(np.int32),
                csr.indices.astype(np.int32),
                csr.data.astype(np.float64),
                MatrixType.CSR,
            )
        except (ValueError, RuntimeError) as exc:
            raise SolverError(
                f"Cholesky factorisation failed ({exc}); the matrix is not positive definite:"
                " is the body held (fixed nodes) for a static solve, are elements inverted?"
            ) from exc
        self.n = csr.shape[0]

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        """x = A^-1 rhs for rhs (n,) or (n, k)."""
        b = np.ascontiguousarray(rhs, dtype=np.float64)
        x = np.empty_like(b)
        self._solver.solve(b, x)
        return x


@dataclass
class PCGReport:
    iterations: int
    converged: bool
    residual: float


def block_pcg(
    apply: Callable[[np.ndarray], np.ndarray],
    precondition: Callable[[np.ndarray], np.ndarray],
    rhs: np.ndarray,
    *,
    rtol: float,
    max_iterations: int,
) -> tuple[np.ndarray, PCGReport]:
    """Conjugate gradients on each column of rhs (n, k), run together.

    Each column has its own step lengths; columns share the operator and preconditioner
    applications, which is where the time goes. Stops when every column's residual is
    below rtol times its right-hand side norm.
    """
    b = rhs
    bnorm = np.linalg.norm(b, axis=0)
    bnorm[bnorm == 0.0] = 1.0
    x = precondition(b)
    r = b - apply(x)
    res = np.max(np.linalg.norm(r, axis=0) / bnorm)
    if res <= rtol:
        return x, PCGReport(0, True, float(res))
    z = precondition(r)
    p = z.copy()
    rz = np.einsum("ij,ij->j", r, z)
    for it in range(1, max_iterations + 1):
        ap = apply(p)
        pap = np.einsum("ij,ij->j", p, ap)
        alpha = np.divide(rz, pap, out=np.zeros_like(rz), where=pap != 0.0)
        x += alpha * p
        r -= alpha * ap
        res = np.max(np.linalg.norm(r, axis=0) / bnorm)
        if res <= rtol:
            return x, PCGReport(it, True, float(res))
        z = precondition(r)
        rz_new = np.einsum("ij,ij->j", r, z)
        beta = np.divide(rz_new, rz, out=np.zeros_like(rz), where=rz != 0.0)
        p = z + beta * p
        rz = rz_new
    return x, PCGReport(max_iterations, False, float(res))
