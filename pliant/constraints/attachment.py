"""Points of the deformable body attached to a dynamic rigid body (SOFA: a RigidMapping of
the points, or an AttachConstraint between the two).

Each attached point p(x) = sum_a w_a x_a stays at the same place in the rigid body's frame:

    delta = p(x) - (c + R r) = 0,   three rows per point (world axes),

with c, R the body's pose and r the point's offset in the body frame, taken where the points
and the body are when the model is built. The rows are bilateral: their multipliers are the
forces the body exerts on the points, of any sign, and the points exert the opposite on the
body. Over a step, delta = delta(q, pose at the start) + h H v_new + h G u_new, G the rows'
dependence on the body's twist (the velocity of the point carried by the body, negated), so
the rows are coupled to the body's motion as contact rows are
(:mod:`pliant.constraints.contact`), and the offset left at the start of a step, if any, is
closed over it. The step eliminates the rows before solving for the actuators and contacts
(:func:`eliminate`): whatever the control, it sees the body and its attached load as one.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg

from pliant.constraints.base import Constraint, EmbeddedPoints, JacobianRows
from pliant.constraints.condensed import CondensedProblem
from pliant.errors import ModelError, SolverError
from pliant.fem import rod_kernels
from pliant.fem.rigid import RigidBody
from pliant.fem.rod import RodBody
from pliant.geometry.rotation import log_map


class Attachment(Constraint):
    """Points of the deformable body held at fixed places of a dynamic rigid body.

    Args:
        points: the attached points, embedded in the deformable body (nodes:
            ``EmbeddedPoints.at_nodes``).
        body: the rigid body (one of the model's `rigid_bodies`). For a body whose motion is
            prescribed (a kinematic body), hold the nodes with
            :class:`pliant.fem.rigid.DrivenNodes` instead.
    """

    role = "attachment"

    def __init__(self, points: EmbeddedPoints, body: RigidBody, *, name: str = "attachment"):
        if not isinstance(body, RigidBody):
            raise ModelError(
                f"{name}: attach to a dynamic RigidBody, got {type(body).__name__} (nodes"
                " carried by a kinematic body are DrivenNodes)"
            )
        if len(points) == 0:
            raise ModelError(f"{name}: no points to attach")
        self.name = name
        self.points = points
        self.body = body
        self.offsets: np.ndarray | None = None  # (k, 3) in the body frame, set by bind
        self.centre = body.position.copy()
        self.rotation = body.rotation.copy()

    def bind(self, rest_positions: np.ndarray) -> None:
        """Take the offsets r of the points in the body frame, from the body's initial pose."""
        arms = self.points.positions(rest_positions) - self.body.position
        self.offsets = arms @ self.body.rotation
        self.centre = self.body.position.copy()
        self.rotation = self.body.rotation.copy()

    def set_pose(self, centre: np.ndarray, rotation: np.ndarray) -> None:
        """The body's pose the rows are taken at (the step's start)."""
        self.centre = np.asarray(centre, dtype=float)
        self.rotation = np.asarray(rotation, dtype=float)

    @property
    def n_rows(self) -> int:
        return 3 * len(self.points)

    def arms(self) -> np.ndarray:
        """(k, 3) R r: the points' places on the body relative to its centre, world axes."""
        if self.offsets is None:
            raise ModelError(f"{self.name}: not part of a model yet (Model binds the offsets)")
        return self.offsets @ self.rotation.T

    def distance(self, x: np.ndarray) -> np.ndarray:
        return (self.points.positions(x) - self.centre - self.arms()).reshape(-1)

    def jacobian(self, x: np.ndarray) -> JacobianRows:
        nodes, weights = self.points.nodes, self.points.weights
        k, m = nodes.shape
        values = np.zeros((k, 3, m, 3))
        for axis in range(3):
            values[:, axis, :, axis] = weights
        return JacobianRows(np.repeat(nodes, 3, axis=0), values.reshape(3 * k, m, 3))

    def twist_rows(self, index: int, n_bodies: int) -> np.ndarray:
        """(3k, 6 n_bodies) G: d delta / d(h u), minus the velocity v + w x a of each point
        carried by body `index` (a: its arm), i.e. the rows [-I, [a]x] on that body."""
        arms = self.arms()
        g = np.zeros((arms.shape[0], 3, 6 * n_bodies))
        g[:, :, 6 * index : 6 * index + 3] = -np.eye(3)
        # [a]x w = a x w, as the matrix of rows (0, -a_z, a_y), (a_z, 0, -a_x), (-a_y, a_x, 0).
        cross = np.zeros((arms.shape[0], 3, 3))
        cross[:, 0, 1], cross[:, 0, 2] = -arms[:, 2], arms[:, 1]
        cross[:, 1, 0], cross[:, 1, 2] = arms[:, 2], -arms[:, 0]
        cross[:, 2, 0], cross[:, 2, 1] = -arms[:, 1], arms[:, 0]
        g[:, :, 6 * index + 3 : 6 * index + 6] = cross
        return g.reshape(-1, 6 * n_bodies)


class Weld(Attachment):
    """Nodes of a rod built into a dynamic rigid body: each keeps its place *and* its
    orientation in the body's frame (a leg clamped into a hub; position rows alone leave the
    rod free to turn about the nodes, a pin).

    Six rows per node: the three of :class:`Attachment`, then three on its orientation,

        delta_R = log(R_i (R Q_i)^T) = 0   (world axes),

    with R_i the node's material frame, R the body's rotation and Q_i = R^T R_i taken at the
    model's build. An increment of a rod's orientation is a spatial spin, so the rows read it
    with the identity and the body's angular velocity with minus the identity: G = [0, -I].
    (The exact derivative of log differs from the identity by O(|delta_R|), and the rows hold
    delta_R at zero: the same first-order linearisation as every other row of the step.)

    Args:
        rod: the model's :class:`pliant.fem.rod.RodBody`.
        nodes: centreline nodes welded to the body.
        body: the rigid body (one of the model's `rigid_bodies`).
    """

    def __init__(self, rod, nodes, body: RigidBody, *, name: str = "weld") -> None:
        if not isinstance(rod, RodBody):
            raise ModelError(
                f"{name}: a weld holds a rod's nodes and frames; got {type(rod).__name__} (a"
                " tetrahedral body's points fix its orientation: use Attachment)"
            )
        nodes = np.asarray(nodes, dtype=np.int64).reshape(-1)
        n = rod.n_centreline
        if nodes.size and (nodes.min() < 0 or nodes.max() >= n):
            raise ModelError(f"{name}: rod nodes must lie in [0, {n}), got {nodes.tolist()}")
        if np.unique(nodes).size != nodes.size:
            raise ModelError(f"{name}: node listed twice in {nodes.tolist()}")
        super().__init__(EmbeddedPoints.at_nodes(nodes), body, name=name)
        self.rod = rod
        self.nodes = nodes
        self.frames: np.ndarray | None = None  # (k, 3, 3) Q_i, set by bind

    def bind(self, rest_positions: np.ndarray) -> None:
        super().bind(rest_positions)
        self.frames = np.einsum(
            "ji,kjl->kil", self.body.rotation, self._node_frames(rest_positions)
        )

    def _node_frames(self, x: np.ndarray) -> np.ndarray:
        return rod_kernels.node_rotations(
            np.ascontiguousarray(x[self.rod.n_centreline + self.nodes])
        )

    @property
    def n_rows(self) -> int:
        return 6 * len(self.points)

    def orientation_error(self, x: np.ndarray) -> np.ndarray:
        """(k, 3) log(R_i (R Q_i)^T): each node's frame against the one the body holds."""
        if self.frames is None:
            raise ModelError(f"{self.name}: not part of a model yet (Model binds the frames)")
        held = np.einsum("ij,kjl->kil", self.rotation, self.frames)
        turned = np.einsum("kij,klj->kil", self._node_frames(x), held)
        return np.array([log_map(r) for r in turned])

    def distance(self, x: np.ndarray) -> np.ndarray:
        return np.concatenate([super().distance(x), self.orientation_error(x).reshape(-1)])

    def jacobian(self, x: np.ndarray) -> JacobianRows:
        placed = super().jacobian(x)
        k, m = self.nodes.size, placed.nodes.shape[1]
        # Orientation rows: the node's spin, in the first of the rows' m slots.
        spins = np.zeros((k, 3, m, 3))
        for axis in range(3):
            spins[:, axis, 0, axis] = 1.0
        turned = np.repeat(self.rod.n_centreline + self.nodes, 3)
        return JacobianRows(
            np.vstack([placed.nodes, np.repeat(turned[:, None], m, axis=1)]),
            np.concatenate([placed.values, spins.reshape(3 * k, m, 3)]),
        )

    def twist_rows(self, index: int, n_bodies: int) -> np.ndarray:
        """The attachment's rows [-I, [a]x], then [0, -I] for each node's orientation."""
        turned = np.zeros((self.nodes.size, 3, 6 * n_bodies))
        turned[:, :, 6 * index + 3 : 6 * index + 6] = -np.eye(3)
        return np.vstack([super().twist_rows(index, n_bodies), turned.reshape(-1, 6 * n_bodies)])


@dataclass(frozen=True)
class Elimination:
    """A problem without its attachment rows (the last ones), and how to recover their
    multipliers: lambda_b = -W_bb^-1 (delta_b,free + W_br lambda_r)."""

    problem: CondensedProblem
    rows: slice
    _factor: tuple
    _coupling: np.ndarray
    _free: np.ndarray

    def full(self, reduced: np.ndarray) -> np.ndarray:
        """lambda for every row of the whole problem from the reduced problem's."""
        attached = -scipy.linalg.cho_solve(self._factor, self._free + self._coupling @ reduced)
        return np.concatenate([reduced, attached])


def eliminate(problem: CondensedProblem) -> Elimination | None:
    """The Schur complement of `problem` on its attachment rows, which must come last: with b
    those rows and r the others, W' = W_rr - W_rb W_bb^-1 W_br, delta' = delta_r - W_rb
    W_bb^-1 delta_b (the rows b held at delta_b = 0 by lambda_b). None without such rows."""
    b = problem.slices.get("attachment")
    if b is None or b.stop == b.start:
        return None
    w, d = problem.compliance, problem.free_distance
    if b.stop != d.size:
        raise SolverError("attachment rows must be the problem's last rows")
    r = slice(0, b.start)
    try:
        factor = scipy.linalg.cho_factor(w[b, b])
    except np.linalg.LinAlgError as exc:
        raise SolverError(
            "the attachment rows' compliance is not positive definite: points attached twice,"
            " or to a body they cannot move with"
        ) from exc
    solved = scipy.linalg.cho_solve(factor, np.column_stack([w[b, r], d[b]]))
    reduced_w = w[r, r] - w[r, b] @ solved[:, :-1]
    reduced_d = d[r] - w[r, b] @ solved[:, -1]
    slices = {role: s for role, s in problem.slices.items() if role != "attachment"}
    reduced = CondensedProblem(0.5 * (reduced_w + reduced_w.T), reduced_d, slices)
    return Elimination(reduced, b, factor, w[b, r], d[b])
