"""Sparse pattern of the stiffness matrix (tetrahedra or hexahedra) restricted to free degrees
of freedom."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from pliant.errors import ModelError


@dataclass(frozen=True)
class StiffnessPattern:
    """CSR pattern on the free DoFs and, per element entry, its position in the data array.

    Attributes:
        indptr, indices: CSR structure (sorted column indices), size n_free.
        scatter: (m, 3 k, 3 k) int64 (k nodes per element), position in `data` of element
            entry (r, c), -1 when the row or column is a fixed DoF.
    """

    n_free: int
    indptr: np.ndarray
    indices: np.ndarray
    scatter: np.ndarray

    @classmethod
    def build(
        cls, tets: np.ndarray, free_index: np.ndarray, couplings: tuple = ()
    ) -> StiffnessPattern:
        """`free_index[d]` is the free-DoF number of full DoF d, or -1 if d is fixed; `tets`
        are the elements' nodes (m, k); `couplings`, groups of nodes (g, j) coupled besides
        the elements (loads between elements): their entries join the pattern, not
        `scatter`."""
        m, size = tets.shape[0], 3 * tets.shape[1]
        dofs = (3 * tets[:, :, None] + np.arange(3)[None, None, :]).reshape(m, size)
        fdofs = free_index[dofs]
        rows = np.broadcast_to(fdofs[:, :, None], (m, size, size))
        cols = np.broadcast_to(fdofs[:, None, :], (m, size, size))
        valid = (rows >= 0) & (cols >= 0)
        n_free = int(free_index.max()) + 1 if free_index.size and free_index.max() >= 0 else 0
        key = rows.astype(np.int64) * max(n_free, 1) + cols
        keys = [key[valid]]
        for group in couplings:
            gd = free_index[(3 * group[:, :, None] + np.arange(3)).reshape(group.shape[0], -1)]
            gr, gc = gd[:, :, None], gd[:, None, :]
            both = (gr >= 0) & (gc >= 0)
            keys.append((gr.astype(np.int64) * max(n_free, 1) + gc)[both])
        uniq, inverse = np.unique(np.concatenate(keys), return_inverse=True)
        scatter = np.full((m, size, size), -1, dtype=np.int64)
        scatter[valid] = inverse.ravel()[: int(valid.sum())]
        urows = uniq // max(n_free, 1)
        indices = (uniq % max(n_free, 1)).astype(np.int32)
        indptr = np.zeros(n_free + 1, dtype=np.int32)
        np.add.at(indptr, urows + 1, 1)
        np.cumsum(indptr, out=indptr)
        return cls(n_free=n_free, indptr=indptr, indices=indices, scatter=scatter)

    def place(self, free_dofs: np.ndarray, what: str) -> tuple:
        """Where the (g, k, k) blocks of groups of free DoFs `free_dofs` (g, k; -1 fixed) go:
        (to_free, the (n_free, g k) sum of the groups' vectors into the free DoFs; valid, the
        (g, k, k) entries of free rows and columns; positions, their places in the data
        array). ModelError names `what` when two of a group's DoFs share no element."""
        n_groups, k = free_dofs.shape
        held = free_dofs.ravel() >= 0
        cols = np.arange(free_dofs.size)
        to_free = sp.csr_matrix(
            (np.ones(held.sum()), (free_dofs.ravel()[held], cols[held])),
            shape=(self.n_free, free_dofs.size),
        )
        rows = np.broadcast_to(free_dofs[:, :, None], (n_groups, k, k))
        columns = np.broadcast_to(free_dofs[:, None, :], (n_groups, k, k))
        valid = (rows >= 0) & (columns >= 0)
        n_free = max(self.n_free, 1)
        entry_rows = np.repeat(np.arange(self.n_free), np.diff(self.indptr))
        keys = entry_rows.astype(np.int64) * n_free + self.indices
        wanted = rows[valid].astype(np.int64) * n_free + columns[valid]
        found = np.searchsorted(keys, wanted)
        if np.any(found >= keys.size) or np.any(keys[np.minimum(found, keys.size - 1)] != wanted):
            raise ModelError(what)
        return to_free, valid, found

    @property
    def nnz(self) -> int:
        return int(self.indices.size)

    def matrix(self, data: np.ndarray) -> sp.csr_matrix:
        return sp.csr_matrix((data, self.indices, self.indptr), shape=(self.n_free, self.n_free))
