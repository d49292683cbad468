"""The constraint layout a condensed model is learned on, and W packed as its upper triangle.

A learned condensed model maps constraint rows to constraint rows, so it only means something
for a robot with the same rows in the same order: actuators, then effectors, then contacts, as
:class:`~pliant.constraints.condensed.CondensedProblem` orders them. The layout also carries
what control needs without the FEM model: the actuators' bounds and the effector rows' axes,
weights and training goals (Eq. 5.6).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from functools import cached_property

import numpy as np

from pliant.constraints.base import Constraint
from pliant.constraints.condensed import CondensedProblem
from pliant.errors import LearnedModelError
from pliant.model import Model

ROLES = ("actuator", "effector", "contact")


@dataclass(frozen=True)
class ActuatorBounds:
    """An actuator's name and bounds: what the inverse QP reads of an actuator (it stands for
    :class:`~pliant.constraints.base.Actuator` in
    :func:`~pliant.constraints.inverse.solve_inverse`)."""

    name: str
    min_force: float = 0.0
    max_force: float = math.inf
    min_displacement: float = -math.inf
    max_displacement: float = math.inf
    max_displacement_change: float | None = None


@dataclass(frozen=True)
class EffectorRows:
    """A position effector's rows: delta_e = weight (p - goal)[axes] for each of its points.

    Attributes:
        goals: the goals the data were collected with, p_goal^train of Eq. 5.6, (points, 3).
    """

    name: str
    axes: tuple[int, ...]
    weight: float
    goals: tuple[tuple[float, float, float], ...]

    @cached_property
    def n_rows(self) -> int:
        return len(self.goals) * len(self.axes)

    def rows(self, points: np.ndarray) -> np.ndarray:
        """weight * points[:, axes] flattened: positions (or goals) in this effector's rows."""
        return self.weight * np.asarray(points, dtype=float).reshape(-1, 3)[:, self.axes].ravel()


@dataclass(frozen=True)
class Layout:
    """The constraint rows of a robot by role, in CondensedProblem order (derived sizes are
    cached: the embedded control loop asks for them at every iteration).

    Attributes:
        contacts: (name, rows) of each set of fixed contact points of §5.1.4, whose
            displacements delta_c are imposed like the actuators'
            (:class:`~pliant.condensed.contact.ContactRobot`).
    """

    actuators: tuple[ActuatorBounds, ...]
    effectors: tuple[EffectorRows, ...]
    contacts: tuple[tuple[str, int], ...] = ()

    @classmethod
    def of(cls, model: Model, contacts: Sequence[Constraint] = ()) -> Layout:
        """The layout of `model` with fixed contact points `contacts`, its effectors' current
        goals taken as the training goals. (Detected contacts come and go with the
        configuration: they are not part of it.)"""
        actuators = tuple(
            ActuatorBounds(
                a.name,
                a.min_force,
                a.max_force,
                a.min_displacement,
                a.max_displacement,
                a.max_displacement_change,
            )
            for a in model.actuators
        )
        effectors = tuple(
            EffectorRows(
                e.name,
                tuple(int(i) for i in e.axes),
                float(e.weight),
                tuple(tuple(float(v) for v in g) for g in e.goals),
            )
            for e in model.effectors
        )
        return cls(actuators, effectors, tuple((c.name, c.n_rows) for c in contacts))

    @cached_property
    def counts(self) -> dict[str, int]:
        """Number of rows of each role."""
        return {
            "actuator": len(self.actuators),
            "effector": sum(e.n_rows for e in self.effectors),
            "contact": sum(rows for _, rows in self.contacts),
        }

    @cached_property
    def n_rows(self) -> int:
        return sum(self.counts.values())

    @cached_property
    def slices(self) -> dict[str, slice]:
        out, start = {}, 0
        for role in ROLES:
            out[role] = slice(start, start + self.counts[role])
            start += self.counts[role]
        return out

    @cached_property
    def n_triangle(self) -> int:
        """Entries of W's upper triangle, diagonal included."""
        return self.n_rows * (self.n_rows + 1) // 2

    @cached_property
    def triangle(self) -> tuple[np.ndarray, np.ndarray]:
        """Row and column indices of W's upper triangle, in packing order."""
        return np.triu_indices(self.n_rows)

    def effector_rows(self, points: np.ndarray) -> np.ndarray:
        """Positions or goals of every effector point, (points, 3) in effector order, as rows."""
        pts = np.asarray(points, dtype=float).reshape(-1, 3)
        sizes = [len(e.goals) for e in self.effectors]
        if pts.shape[0] != sum(sizes):
            raise LearnedModelError(
                f"the effectors have {sum(sizes)} points in all, got {pts.shape[0]} positions"
            )
        parts = np.split(pts, np.cumsum(sizes)[:-1])
        return np.concatenate([e.rows(p) for e, p in zip(self.effectors, parts, strict=True)])

    @cached_property
    def training_goal_rows(self) -> np.ndarray:
        """p_goal^train of Eq. 5.6 as effector rows."""
        return self.effector_rows(np.array([g for e in self.effectors for g in e.goals]))

    def pack(self, problem: CondensedProblem) -> tuple[np.ndarray, np.ndarray]:
        """(W's upper triangle, delta_free) of a condensed problem with this layout."""
        self._check_slices(problem.slices, "the condensed problem")
        rows, cols = self.triangle
        return problem.compliance[rows, cols], problem.free_distance.copy()

    def unpack(self, w_triangle: np.ndarray, free_distance: np.ndarray) -> CondensedProblem:
        """The condensed problem whose symmetric W has this upper triangle."""
        n = self.n_rows
        w = np.zeros((n, n))
        rows, cols = self.triangle
        w[rows, cols] = w_triangle
        w[cols, rows] = w_triangle
        return CondensedProblem(w, np.asarray(free_distance, dtype=float), self.slices)

    def check(self, model: Model) -> None:
        """Raise LearnedModelError, naming the first difference, unless `model` has these
        actuators, effectors and contacts (names, axes and rows; not bounds nor goals)."""
        self.check_matches(Layout.of(model), model.name)

    def check_matches(self, other: Layout, what: str) -> None:
        """`check` against another layout, that of `what` (a robot, a dataset)."""
        mine = [a.name for a in self.actuators]
        theirs = [a.name for a in other.actuators]
        if mine != theirs:
            raise LearnedModelError(
                f"{what} has actuators {theirs}; the condensed model learned {mine}"
            )
        mine = [(e.name, e.axes, len(e.goals)) for e in self.effectors]
        theirs = [(e.name, e.axes, len(e.goals)) for e in other.effectors]
        if mine != theirs:
            raise LearnedModelError(
                f"{what} has effectors (name, axes, points) {theirs}; the condensed model"
                f" learned {mine}"
            )
        if self.contacts != other.contacts:
            raise LearnedModelError(
                f"{what} has contacts (name, rows) {list(other.contacts)}; the condensed"
                f" model learned {list(self.contacts)}"
            )

    def _check_slices(self, slices: dict[str, slice], what: str) -> None:
        for role, expected in self.slices.items():
            got = slices.get(role, slice(expected.start, expected.start))
            if (got.start, got.stop) != (expected.start, expected.stop):
                raise LearnedModelError(
                    f"{what} has {role} rows {got.start}:{got.stop}, the layout"
                    f" {expected.start}:{expected.stop}"
                )

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, data: dict) -> Layout:
        try:
            return cls(
                tuple(ActuatorBounds(**a) for a in data["actuators"]),
                tuple(
                    EffectorRows(
                        e["name"],
                        tuple(e["axes"]),
                        e["weight"],
                        tuple(tuple(g) for g in e["goals"]),
                    )
                    for e in data["effectors"]
                ),
                tuple((name, rows) for name, rows in data["contacts"]),
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise LearnedModelError(f"malformed constraint layout: {exc!r}") from exc
