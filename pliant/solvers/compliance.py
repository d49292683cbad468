"""Compliance of a body's contact points, kept for the life of one factorisation.

A contact row is a frame direction applied to the displacement of a point carried by the body,
p = sum_a w_a x_a, so the contact block of H is H_c = F P, with F the block diagonal of the
contacts' frames (3 x 3 each) and P the rows that read the points (3 per point). Every product
the step needs follows from Z_p = A^-1 P_p^T, three columns per point:

    H_c A^-1 H_c^T = F (P Z) F^T,   H_c A^-1 H_a^T = F P (A^-1 H_a^T),   A^-1 H_c^T l = Z F^T l.

While the factorisation of A is unchanged (the lagged tangent keeps it over many steps), Z_p is
too; it is solved once for each point when the point first comes into contact, instead of three
columns per contact at every step. Those are the same numbers: the results differ from solving
all columns at every step only by round-off.
"""

from __future__ import annotations

import numpy as np

from pliant.constraints.base import EmbeddedPoints
from pliant.solvers import compliance_kernels as kernels


class PointCompliance:
    """Columns Z_p = A^-1 P_p^T of embedded points for the current factorisation.

    Args:
        points: the points (a model's colliding points).
        free_index: full DoF -> free DoF (-1 for a fixed DoF), the body's `free_index`.
    """

    def __init__(self, points: EmbeddedPoints, free_index: np.ndarray) -> None:
        self.points = points
        # Free DoF of (point, node, axis), -1 where the node is held.
        self._dofs = free_index[3 * points.nodes[:, :, None] + np.arange(3)]
        self._weights = np.where(self._dofs >= 0, points.weights[:, :, None], 0.0)
        self.n_free = int(np.count_nonzero(free_index >= 0))
        self._slot = np.full(len(points), -1, dtype=np.int64)
        self._store = np.zeros((self.n_free, 0), order="F")
        self._used = 0
        self._factorisation: int | None = None
        self.solved_points = 0

    def reset(self) -> None:
        """Forget every column (the factorisation changed)."""
        self._slot[:] = -1
        self._used = 0

    def columns(self, solve, factorisation: int, index: np.ndarray) -> np.ndarray:
        """Slots of the points `index` in `store`, solving the missing ones with `solve`
        (A^-1 of the factorisation numbered `factorisation`)."""
        if factorisation != self._factorisation:
            self.reset()
            self._factorisation = factorisation
        missing = np.unique(index[self._slot[index] < 0])
        if missing.size:
            rhs = np.zeros((self.n_free, 3 * missing.size), order="F")
            for axis in range(3):
                dofs = self._dofs[missing, :, axis]  # (k, 4)
                cols = (3 * np.arange(missing.size) + axis)[:, None]
                keep = dofs >= 0
                np.add.at(
                    rhs,
                    (dofs[keep], np.broadcast_to(cols, dofs.shape)[keep]),
                    self._weights[missing, :, axis][keep],
                )
            z = solve(rhs)
            need = self._used + missing.size
            if self._used == 0:  # a new factorisation's first columns: kept as solved
                self._store = z
            else:
                if 3 * need > self._store.shape[1]:
                    width = 3 * max(need, 2 * self._store.shape[1] // 3)
                    grown = np.zeros((self.n_free, width), order="F")
                    grown[:, : 3 * self._used] = self._store[:, : 3 * self._used]
                    self._store = grown
                self._store[:, 3 * self._used : 3 * need] = z
            self._slot[missing] = np.arange(self._used, need)
            self._used = need
            self.solved_points += missing.size
        return self._slot[index]

    @property
    def store(self) -> np.ndarray:
        """(n_free, 3 * slots) columns; slot s holds the point's three columns 3s..3s+2."""
        return self._store[:, : 3 * self._used]

    def read(self, index: np.ndarray, values: np.ndarray) -> np.ndarray:
        """P_p values for each point of `index`: (k, 3, ...) from free-DoF values (n_free, ...)."""
        dofs = self._dofs[index]  # (k, 4, 3)
        gathered = values[np.where(dofs >= 0, dofs, 0)]  # (k, 4, 3, ...)
        w = self._weights[index]
        w = w.reshape(w.shape + (1,) * (gathered.ndim - 3))
        return np.sum(w * gathered, axis=1)

    def block(self, index: np.ndarray, slots: np.ndarray) -> np.ndarray:
        """P A^-1 P^T between the points of `index`: (3k, 3k)."""
        return kernels.point_block(self._store, self._dofs[index], self._weights[index], slots)

    def framed_rows(self, index: np.ndarray, frames: np.ndarray, values: np.ndarray) -> np.ndarray:
        """F P values: the rows (3k, c) of the frames (k, 3, 3) on the points of `index`
        applied to free-DoF values (n_free, c)."""
        return kernels.framed_rows(frames, self._dofs[index], self._weights[index], values)

    def apply(self, slots: np.ndarray, forces: np.ndarray) -> np.ndarray:
        """A^-1 P^T f for point forces `forces` (k, 3) on the points held in `slots`."""
        used, where = np.unique(slots, return_inverse=True)
        if 2 * used.size >= self._used:  # most kept columns are in use: no copy
            f = np.zeros((self._used, 3))
            np.add.at(f, slots, forces)
            return self.store @ f.reshape(-1)
        f = np.zeros((used.size, 3))
        np.add.at(f, where, forces)
        cols = (3 * used[:, None] + np.arange(3)).reshape(-1)
        return self._store[:, cols] @ f.reshape(-1)


class PointRows:
    """Rows of cables and position effectors read through their points' compliance.

    A cable's row is sum_j g_j . P_j over its embedded points (g_j = d delta / d p_j), and a
    position effector's rows are the weighted axes of P_j; so with G the (rows, 3 points)
    matrix of those coefficients, H = G P and W = G (P Z) G^T, A^-1 H^T lambda = Z G^T lambda,
    from the columns Z kept for the factorisation by a :class:`PointCompliance`. Worth it for
    robots whose cables run through few points (the Diamond: one each), whose columns are then
    solved once per factorisation instead of one per row at every step.

    Args:
        constraints: the rows' constraints in the order of the constraint space.
        free_index: the body's full DoF -> free DoF map.
    """

    def __init__(self, constraints: list, free_index: np.ndarray) -> None:
        self.constraints = constraints
        nodes, weights, self._offsets = [], [], []
        varying, varying_rows, varying_points = [], [], []  # one-row constraints, (row, point)
        constant = []  # (first row, first point column, coefficients) of the constant rows
        self._fixed: list[tuple[int, object]] = []  # constraints with constant rows, first rows
        self.slices: dict[str, slice] = {}
        row = 0
        for c in constraints:
            form = c.point_row_form()
            if form is None:
                raise TypeError(f"{type(c).__name__} rows are not combinations of point rows")
            off = sum(len(n) for n in nodes)
            self._offsets.append(off)
            nodes.append(form.points.nodes)
            weights.append(form.points.weights)
            if form.coefficients is None:
                varying.append(c)
                varying_rows.append(row)
                varying_points += [(row, off + j) for j in range(len(form.points))]
            else:
                self._fixed.append((row, c))
                constant.append((row, 3 * off, form.coefficients))
            role = self.slices.get(c.role)
            self.slices[c.role] = slice(row if role is None else role.start, row + c.n_rows)
            row += c.n_rows
        self.n_rows = row
        for role in ("actuator", "effector", "contact"):
            self.slices.setdefault(role, slice(row, row))
        points = EmbeddedPoints.__new__(EmbeddedPoints)
        points.nodes = np.concatenate(nodes)
        points.weights = np.concatenate(weights)
        self.n_points = len(points)
        self.cache = PointCompliance(points, free_index)
        self._index = np.arange(self.n_points)
        # The rows whose point gradients change with the configuration, evaluated together by
        # their class's bundle (the cables').
        self._varying = None
        if varying:
            kind = type(varying[0])
            if any(type(c) is not kind for c in varying) or any(c.n_rows != 1 for c in varying):
                raise TypeError("varying point rows must be one-row constraints of one class")
            self._varying = kind.bundle(varying)
            if not hasattr(self._varying, "point_gradients"):
                raise TypeError(f"{kind.__name__}'s bundle gives no point gradients")
        self._varying_rows = np.array(varying_rows, dtype=np.int64)
        pairs = np.array(varying_points, dtype=np.int64).reshape(-1, 2)
        self._g_rows = pairs[:, :1]
        self._g_cols = 3 * pairs[:, 1:] + np.arange(3)
        self._g0 = np.zeros((self.n_rows, 3 * self.n_points))
        for r, col, block in constant:
            self._g0[r : r + block.shape[0], col : col + block.shape[1]] = block
        self._block: tuple[int, np.ndarray] | None = None

    @classmethod
    def build(cls, constraints: list, free_index: np.ndarray) -> PointRows | None:
        """PointRows for `constraints` if all give a point-row form (cables, position
        effectors: :meth:`~pliant.constraints.base.Constraint.point_row_form`) and their
        points' columns (3 per point) are no more than 4 steps' worth of row columns."""
        if not constraints:
            return None
        try:
            rows = cls(constraints, free_index)
        except TypeError:
            return None
        return rows if 0 < 3 * rows.n_points <= 4 * rows.n_rows else None

    def evaluate(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The rows' distances delta(x) (rows,) and coefficients G (rows, 3 points) at x."""
        g = self._g0.copy()
        delta = np.zeros(self.n_rows)
        if self._varying is not None:
            delta[self._varying_rows], grads = self._varying.point_gradients(x)
            g[self._g_rows, self._g_cols] = grads
        for row, c in self._fixed:
            delta[row : row + c.n_rows] = c.distance(x)
        return delta, g

    def condense(self, solve, factorisation: int, x: np.ndarray, motion: np.ndarray):
        """(delta(x), W without h^2, H motion, lambda -> A^-1 H^T lambda) for the factorisation
        numbered `factorisation` (A^-1: `solve`), the rows taken at x."""
        delta, g = self.evaluate(x)
        slots = self.cache.columns(solve, factorisation, self._index)
        if self._block is None or self._block[0] != factorisation:  # P A^-1 P^T, kept with A
            self._block = (factorisation, self.cache.block(self._index, slots))
        w = g @ self._block[1] @ g.T
        moved = g @ self.cache.read(self._index, motion).reshape(-1)

        def response(lam: np.ndarray) -> np.ndarray:
            return self.cache.apply(slots, (g.T @ lam).reshape(-1, 3))

        return delta, w, moved, response
