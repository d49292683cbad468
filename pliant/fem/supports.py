"""Nodes held on a line or a plane of any direction (SOFA's ProjectToLineConstraint and
ProjectToPlaneConstraint), by projection.

A node on the plane through its rest position with unit normal n may move by P u with
P = I - n n^T; on the line with unit direction d, by P u with P = d d^T. The body gathers the
nodes' blocks into one projection of its free DoFs (:meth:`pliant.fem.body.TetBody`,
``projections=``), and the solvers solve the projected system, as SOFA's projective
constraints do (its ``projectResponse``): with A the step's matrix and b its right-hand side,

    du = P (P A P + s (I - P))^-1 P b,

which is the minimiser of the step's quadratic model over the allowed motions (s > 0 only
keeps the matrix regular on the held directions, whose result the outer P discards). Every
increment then lies in the allowed directions, so a node that starts on its plane or line
stays on it exactly, in the static and the dynamic solvers alike (:mod:`pliant.solvers.system`).
Axis-aligned cases are cheaper as held components (``TetBody(fixed_dofs=...)``).
"""

from __future__ import annotations

import numpy as np

from pliant.errors import ModelError


def _unit(vector, what: str) -> np.ndarray:
    v = np.asarray(vector, dtype=float).reshape(-1)
    norm = float(np.linalg.norm(v)) if v.shape == (3,) else 0.0
    if not (np.isfinite(norm) and norm > 0.0):
        raise ModelError(f"{what} must be a finite non-zero 3-vector, got {vector!r}")
    return v / norm


class Projection:
    """Base of the projections: `nodes` (k,) and their blocks `matrices` (k, 3, 3), the
    orthogonal projectors onto each node's allowed motions."""

    nodes: np.ndarray
    matrices: np.ndarray
    kind: str

    def held_directions(self) -> np.ndarray:
        """(k, m, 3) unit directions along which each node is held (m = 1 or 2)."""
        raise NotImplementedError

    def check_on(self, positions: np.ndarray, origin, *, tolerance: float) -> None:
        """Raise when a node is off the line or plane through `origin` (SOFA projects such a
        node there at its start; Pliant's rest shape is the mesh's)."""
        if self.nodes.max() >= len(positions):
            raise ModelError(f"node indices must lie in [0, {len(positions)})")
        offset = positions[self.nodes] - np.asarray(origin, dtype=float)
        away = np.linalg.norm(np.einsum("kmi,ki->km", self.held_directions(), offset), axis=1)
        if away.size and away.max() > tolerance:
            raise ModelError(
                f"node {int(self.nodes[np.argmax(away)])} lies {away.max():.3g} off the {self.kind}"
                " it is held on: place the mesh's nodes on it"
            )


def _nodes(nodes, what: str) -> np.ndarray:
    idx = np.unique(np.asarray(nodes, dtype=np.int64).reshape(-1))
    if idx.size == 0 or idx.min() < 0:
        raise ModelError(f"{what}: give non-negative node indices")
    return idx


class OnPlane(Projection):
    """Nodes that slide on the plane through their rest positions with normal `normal`
    (SOFA's ProjectToPlaneConstraint): P = I - n n^T."""

    kind = "plane"

    def __init__(self, nodes, normal) -> None:
        self.nodes = _nodes(nodes, "OnPlane")
        self.normal = _unit(normal, "OnPlane: the normal")
        block = np.eye(3) - np.outer(self.normal, self.normal)
        self.matrices = np.broadcast_to(block, (self.nodes.size, 3, 3)).copy()

    def held_directions(self) -> np.ndarray:
        return np.broadcast_to(self.normal, (self.nodes.size, 1, 3))


class OnLine(Projection):
    """Nodes that slide on the line through their rest positions along `direction` (SOFA's
    ProjectToLineConstraint): P = d d^T."""

    kind = "line"

    def __init__(self, nodes, direction) -> None:
        self.nodes = _nodes(nodes, "OnLine")
        self.direction = _unit(direction, "OnLine: the direction")
        self.matrices = np.broadcast_to(
            np.outer(self.direction, self.direction), (self.nodes.size, 3, 3)
        ).copy()

    def held_directions(self) -> np.ndarray:
        # The two unit vectors orthogonal to d: the last right-singular vectors of d^T.
        normals = np.linalg.svd(self.direction[None, :])[2][1:]
        return np.broadcast_to(normals, (self.nodes.size, 2, 3))
