"""Sparse pattern of the tetrahedral stiffness matrix restricted to free degrees of freedom."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp


@dataclass(frozen=True)
class StiffnessPattern:
    """CSR pattern on the free DoFs and, per element entry, its position in the data array.

    Attributes:
        indptr, indices: CSR structure (sorted column indices), size n_free.
        scatter: (m, 12, 12) int64, position in `data` of element entry (r, c), -1 when the
            row or column is a fixed DoF.
    """

    n_free: int
    indptr: np.ndarray
    indices: np.ndarray
    scatter: np.ndarray

    @classmethod
    def build(cls, tets: np.ndarray, free_index: np.ndarray) -> StiffnessPattern:
        """`free_index[d]` is the free-DoF number of full DoF d, or -1 if d is fixed."""
        m = tets.shape[0]
        dofs = (3 * tets[:, :, None] + np.arange(3)[None, None, :]).reshape(m, 12)
        fdofs = free_index[dofs]
        rows = np.broadcast_to(fdofs[:, :, None], (m, 12, 12))
        cols = np.broadcast_to(fdofs[:, None, :], (m, 12, 12))
        valid = (rows >= 0) & (cols >= 0)
        n_free = int(free_index.max()) + 1 if free_index.size and free_index.max() >= 0 else 0
        key = rows.astype(np.int64) * max(n_free, 1) + cols
        uniq, inverse = np.unique(key[valid], return_inverse=True)
        scatter = np.full((m, 12, 12), -1, dtype=np.int64)
        scatter[valid] = inverse.ravel()
        urows = uniq // max(n_free, 1)
        indices = (uniq % max(n_free, 1)).astype(np.int32)
        indptr = np.zeros(n_free + 1, dtype=np.int32)
        np.add.at(indptr, urows + 1, 1)
        np.cumsum(indptr, out=indptr)
        return cls(n_free=n_free, indptr=indptr, indices=indices, scatter=scatter)

    @property
    def nnz(self) -> int:
        return int(self.indices.size)

    def matrix(self, data: np.ndarray) -> sp.csr_matrix:
        return sp.csr_matrix((data, self.indices, self.indptr), shape=(self.n_free, self.n_free))
