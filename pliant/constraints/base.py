"""The narrow interface every constraint implements, and the embedding of points in a mesh.

A constraint contributes rows to the constraint space: a characteristic distance delta_i(x)
and its Jacobian H_i = d delta_i / dx. Actuators add a control mode and bounds. The solvers only
see these rows, so a new actuator or contact type never touches them.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Literal

import numpy as np

from pliant.errors import ConstraintError, ModelError
from pliant.mesh import locate_points
from pliant.mesh.hexmesh import HexMesh
from pliant.mesh.tetmesh import TetMesh


@dataclass(frozen=True)
class JacobianRows:
    """Sparse rows of H: row i depends on nodes[i, :] with gradients values[i, :, :] (3-vectors)."""

    nodes: np.ndarray  # (r, k) int64
    values: np.ndarray  # (r, k, 3)


class EmbeddedPoints:
    """Points carried by the mesh: p_j = sum_a w_ja x[node_ja] over the nodes of an element.

    A point inside the mesh gets its barycentric coordinates in the element containing it, as
    SOFA's BarycentricMapping does. A point outside (up to `tolerance` from the mesh) is, with
    ``outside="project"`` (Pliant's default), moved onto its nearest element (coordinates
    clamped to [0, 1]); with ``outside="keep"`` (SOFA's behaviour, the default of scenes read by
    :mod:`pliant.sofa`), kept where it is, with its barycentric coordinates (some negative) in
    the element whose centre is nearest. In a hexahedral mesh the weights are the trilinear
    shape functions of the containing hexahedron (eight per point).
    """

    def __init__(
        self,
        mesh: TetMesh | HexMesh,
        points: np.ndarray,
        *,
        tolerance: float | None = None,
        outside: Literal["project", "keep"] = "project",
    ) -> None:
        """Embed `points`; `tolerance` is the largest distance outside the mesh accepted
        (default 1 % of the bounding-box diagonal), `outside` how such a point is attached."""
        pts = np.atleast_2d(np.asarray(points, dtype=float))
        if pts.ndim != 2 or pts.shape[1] != 3 or pts.shape[0] == 0:
            raise ModelError(f"points must be a non-empty (k, 3) array, got shape {pts.shape}")
        if not np.all(np.isfinite(pts)):
            raise ModelError("points must be finite")
        if tolerance is None:
            tolerance = 0.01 * float(np.linalg.norm(np.ptp(mesh.points, axis=0)))
        if isinstance(mesh, HexMesh):
            self.nodes, self.weights = mesh.embed(pts, tolerance=tolerance, outside=outside)
            return
        tet_index, bary = locate_points(mesh, pts, tolerance=tolerance, outside=outside)
        self.nodes = np.ascontiguousarray(mesh.tets[tet_index], dtype=np.int64)
        self.weights = np.ascontiguousarray(bary, dtype=float)

    @classmethod
    def at_nodes(cls, node_indices: np.ndarray) -> EmbeddedPoints:
        obj = cls.__new__(cls)
        idx = np.asarray(node_indices, dtype=np.int64).reshape(-1)
        obj.nodes = np.zeros((idx.size, 4), dtype=np.int64)
        obj.nodes[:, 0] = idx
        obj.weights = np.zeros((idx.size, 4))
        obj.weights[:, 0] = 1.0
        return obj

    @classmethod
    def on_rod(cls, rod, arc_lengths) -> EmbeddedPoints:
        """Points of a rod's centreline at rest arc lengths (a :class:`pliant.fem.rod.RodBody`):
        interpolated between the two nodes around each."""
        nodes, weights = rod.interpolation(arc_lengths)
        obj = cls.at_nodes(nodes[:, 0])
        obj.nodes[:, 1] = nodes[:, 1]
        obj.weights[:, :2] = weights
        return obj

    @classmethod
    def stack(cls, parts: list[EmbeddedPoints]) -> EmbeddedPoints:
        """The points of `parts`, in order, as one set; a point read through fewer nodes than
        the widest gets node 0 with weight 0 in the spare slots."""
        width = max(p.nodes.shape[1] for p in parts)
        obj = cls.__new__(cls)
        obj.nodes = np.vstack(
            [np.pad(p.nodes, ((0, 0), (0, width - p.nodes.shape[1]))) for p in parts]
        )
        obj.weights = np.vstack(
            [np.pad(p.weights, ((0, 0), (0, width - p.weights.shape[1]))) for p in parts]
        )
        return obj

    def subset(self, index) -> EmbeddedPoints:
        """The points `index` (an index or indices) of these, with their embedding."""
        obj = type(self).__new__(type(self))
        picked = np.atleast_1d(np.asarray(index, dtype=np.int64))
        obj.nodes, obj.weights = self.nodes[picked].copy(), self.weights[picked].copy()
        return obj

    #: p is linear in the nodes' positions, with fixed weights: a point's compliance columns
    #: stay valid for a factorisation's life (:class:`pliant.solvers.compliance.PointCompliance`).
    #: A mapping that is not (a skinned surface, :class:`pliant.proxy.Skinning`) says False.
    linear = True

    def __len__(self) -> int:
        return int(self.nodes.shape[0])

    def positions(self, x: np.ndarray) -> np.ndarray:
        return np.einsum("ka,kai->ki", self.weights, x[self.nodes])

    def displacement(self, x: np.ndarray, increment: np.ndarray) -> np.ndarray:
        """(k, 3) the points' displacement under a nodal `increment` from positions `x` (to
        first order; exactly, for points embedded linearly)."""
        return self.positions(increment)

    def rows(self, x: np.ndarray, index: np.ndarray, directions: np.ndarray) -> JacobianRows:
        """Rows d . dp of the points `index`, one per direction: `directions` (k, r, 3) gives
        r directions for each of the k points; rows ordered point by point."""
        return embedded_rows(self.nodes[index], self.weights[index], directions)


def embedded_rows(nodes: np.ndarray, weights: np.ndarray, directions: np.ndarray) -> JacobianRows:
    """Rows d . p of k points p = sum_a w_a x_a (`nodes`, `weights`: (k, m)), r directions
    (k, r, 3) each, ordered point by point."""
    k, m = nodes.shape
    r = directions.shape[1]
    values = weights[:, None, :, None] * directions[:, :, None, :]
    return JacobianRows(
        np.repeat(nodes[:, None, :], r, axis=1).reshape(k * r, m), values.reshape(k * r, m, 3)
    )


@dataclass(frozen=True)
class PointRowForm:
    """How a constraint's rows read the positions of its embedded points, for solvers that
    condense in the points' space (:class:`pliant.solvers.compliance.PointRows`).

    points: the embedded points the rows read.
    coefficients: (n_rows, 3 k) constant d delta / d p when the rows are affine in the points'
        positions (position effectors); None for one row whose gradient changes with the
        configuration, given by its class's bundle as ``point_gradients(x)`` (cables).
    """

    points: EmbeddedPoints
    coefficients: np.ndarray | None


class Constraint(ABC):
    """A set of constraint rows: distances delta(x) and Jacobian H(x).

    Besides its rows, a constraint tells the solvers what it needs of them through three
    answers, so that no solver tests constraint types: :meth:`point_row_form` (rows that are
    combinations of point positions), :attr:`rigid_body` (rows on a rigid body's motion) and,
    for actuators, :meth:`Actuator.augmented_nodes`.
    """

    role: Literal["actuator", "effector", "contact"]
    name: str
    # The rigid body of the model whose motion the rows read (None: the deformable body).
    rigid_body = None

    @property
    @abstractmethod
    def n_rows(self) -> int: ...

    @abstractmethod
    def distance(self, x: np.ndarray) -> np.ndarray:
        """delta(x), shape (n_rows,)."""

    @abstractmethod
    def jacobian(self, x: np.ndarray) -> JacobianRows:
        """H(x) as sparse rows."""

    def distance_and_jacobian(self, x: np.ndarray) -> tuple[np.ndarray, JacobianRows]:
        """Both at once; constraints that share work between them override this."""
        return self.distance(x), self.jacobian(x)

    def point_row_form(self) -> PointRowForm | None:
        """The rows as combinations of embedded points' positions, or None when they are not
        (the solver then condenses them through the whole body's DoFs)."""
        return None

    @classmethod
    def bundle(cls, constraints: list[Constraint]) -> Constraint | None:
        """An object evaluating several constraints of this class at once (same rows, same
        order, with `role`, `n_rows`, `distance` and `jacobian`), or None if the class has
        no faster joint evaluation."""
        return None


def _check_real(name: str, value: float) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError) as exc:
        raise ConstraintError(f"{name} must be a number, got {value!r}") from exc
    if math.isnan(v):
        raise ConstraintError(f"{name} is NaN")
    return v


def _check_interval(name: str, kind: str, low: float, high: float) -> None:
    """ConstraintError unless [low, high] admits a finite value of `kind`."""
    if low == math.inf or high == -math.inf:
        raise ConstraintError(
            f"{name}: a {kind} bound of {low} to {high} admits no finite {kind}"
            f" (min_{kind} < inf, max_{kind} > -inf)"
        )
    if low > high:
        raise ConstraintError(
            f"{name}: min_{kind} {low} > max_{kind} {high}: no {kind} is admissible"
        )


class Actuator(Constraint):
    """One actuation row with a control mode and bounds (SoftRobots' parameters).

    Args:
        mode: "force" (lambda imposed: cable tension, cavity pressure) or "displacement"
            (delta imposed: cable shortening, cavity volume growth).
        value: initial command in that mode.
        min_force, max_force: effort bounds on lambda.
        min_displacement, max_displacement: course bounds on delta.
        max_displacement_change: largest change of delta in one step (None: unbounded).
        change_reference: what that change is measured from: "last" (Pliant's default), the
            displacement at the end of the last step; "lagged" (SoftRobots' maxDispVariation,
            the default of scenes read by :mod:`pliant.sofa`), the displacement at the end of
            the step before, which SoftRobots stores when it solves a step, before that step's
            correction moves the body: delta_n <= delta_{n-2} + max_displacement_change, so
            a ramp met exactly climbs every other step (1, 1, 2, 2, 3, ... mm at 1 mm a step).
    """

    role = "actuator"

    def __init__(
        self,
        *,
        name: str,
        mode: Literal["force", "displacement"] = "displacement",
        value: float = 0.0,
        min_force: float = 0.0,
        max_force: float = math.inf,
        min_displacement: float = -math.inf,
        max_displacement: float = math.inf,
        max_displacement_change: float | None = None,
        change_reference: Literal["last", "lagged"] = "last",
    ) -> None:
        self.name = name
        self.mode = mode
        self.value = value
        self.min_force = _check_real("min_force", min_force)
        self.max_force = _check_real("max_force", max_force)
        self.min_displacement = _check_real("min_displacement", min_displacement)
        self.max_displacement = _check_real("max_displacement", max_displacement)
        _check_interval(name, "force", self.min_force, self.max_force)
        _check_interval(name, "displacement", self.min_displacement, self.max_displacement)
        if max_displacement_change is not None:
            max_displacement_change = _check_real(
                "max_displacement_change", max_displacement_change
            )
            if max_displacement_change <= 0:
                raise ConstraintError(f"{name}: max_displacement_change must be > 0")
        self.max_displacement_change = max_displacement_change
        if change_reference not in ("last", "lagged"):
            raise ConstraintError(
                f"{name}: change_reference must be 'last' or 'lagged', got {change_reference!r}"
            )
        self.change_reference = change_reference

    @property
    def mode(self) -> str:
        return self._mode

    @mode.setter
    def mode(self, mode: str) -> None:
        if mode not in ("force", "displacement"):
            raise ConstraintError(
                f"{self.name}: mode must be 'force' or 'displacement', got {mode!r}"
            )
        self._mode = mode

    @property
    def value(self) -> float:
        return self._value

    @value.setter
    def value(self, value: float) -> None:
        v = _check_real(f"{self.name} command", value)
        if math.isinf(v):
            raise ConstraintError(f"{self.name}: the command must be finite, got {v}")
        self._value = v

    @property
    def n_rows(self) -> int:
        return 1

    def augmented_nodes(self) -> np.ndarray | None:
        """The nodes whose DoFs a held course of this row couples, when the static solver's
        consistent Newton step should augment the row (a displacement held on a few DoFs), or
        None (the default: no augmentation)."""
        return None


def change_reference(actuators: list[Actuator], state) -> np.ndarray:
    """The displacement each actuator's largest change per step is measured from, for the step
    that starts from `state` (see :class:`Actuator`'s `change_reference`)."""
    last = state.displacement
    if not actuators:
        return last
    # States that do not keep the displacement before (a reduced model's) measure from the last.
    before = getattr(state, "displacement_before", last)
    before = before if before.size == last.size else last
    lagged = np.array(
        [getattr(a, "change_reference", "last") == "lagged" for a in actuators], dtype=bool
    )
    if last.size != lagged.size or not lagged.any():
        return last
    return np.where(lagged, before, last)


def actuator_bounds(
    actuators: list[Actuator], previous_displacement: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Effort bounds (lo, hi) and the course bounds (dmin, dmax) of this step: the course
    narrowed to previous_displacement +- max_displacement_change where that is set."""
    lo = np.array([a.min_force for a in actuators])
    hi = np.array([a.max_force for a in actuators])
    dmin = np.array([a.min_displacement for a in actuators])
    dmax = np.array([a.max_displacement for a in actuators])
    for i, a in enumerate(actuators):
        if a.max_displacement_change is not None:
            dmin[i] = max(dmin[i], previous_displacement[i] - a.max_displacement_change)
            dmax[i] = min(dmax[i], previous_displacement[i] + a.max_displacement_change)
    return lo, hi, dmin, dmax
