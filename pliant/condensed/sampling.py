"""Where the data are taken: scrambled Halton points for training, random points for testing.

Thesis §5.1.2: the training set fills the box of active-constraint displacements (and design
parameters) with a scrambled Halton sequence, more evenly than a grid in many dimensions; the
test set, 25 % of the training size, is drawn uniformly at random in the same box.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.stats import qmc

from pliant.errors import DatasetError


@dataclass(frozen=True)
class Box:
    """An axis-aligned box [low, high] in R^d."""

    low: np.ndarray
    high: np.ndarray

    def __post_init__(self) -> None:
        try:
            low = np.asarray(self.low, dtype=float).reshape(-1)
            high = np.asarray(self.high, dtype=float).reshape(-1)
        except (TypeError, ValueError) as exc:
            raise DatasetError(f"box bounds must be numbers, got {self.low}, {self.high}") from exc
        if low.shape != high.shape:
            raise DatasetError(f"box bounds of {low.size} and {high.size} values")
        if not (np.all(np.isfinite(low)) and np.all(np.isfinite(high)) and np.all(low <= high)):
            raise DatasetError(f"box bounds must be finite with low <= high, got {low}, {high}")
        object.__setattr__(self, "low", low)
        object.__setattr__(self, "high", high)

    @property
    def dim(self) -> int:
        return self.low.size

    def scale(self, unit: np.ndarray) -> np.ndarray:
        """Points of the unit cube mapped into the box."""
        return self.low + unit * (self.high - self.low)

    def distance(self, points: np.ndarray) -> np.ndarray:
        """Euclidean distance of each point to the box (0 inside)."""
        p = np.atleast_2d(points)
        outside = np.maximum(self.low - p, 0.0) + np.maximum(p - self.high, 0.0)
        return np.linalg.norm(outside, axis=1)


def halton(box: Box, n: int, rng: np.random.Generator) -> np.ndarray:
    """n scrambled Halton points in the box (scipy.stats.qmc), (n, dim)."""
    return box.scale(qmc.Halton(box.dim, scramble=True, seed=rng).random(n))


def uniform(box: Box, n: int, rng: np.random.Generator) -> np.ndarray:
    """n points drawn uniformly at random in the box, (n, dim)."""
    return box.scale(rng.random((n, box.dim)))


def train_test_points(
    box: Box, n_train: int, n_test: int, *, seed: int | Sequence[int] = 0
) -> dict[str, np.ndarray]:
    """{"train": n_train Halton points, "test": n_test random points}; the two streams come
    from independent children of `seed`."""
    train_rng, test_rng = (np.random.default_rng(s) for s in np.random.SeedSequence(seed).spawn(2))
    return {
        "train": halton(box, n_train, train_rng),
        "test": uniform(box, n_test, test_rng),
    }


def grouped_train_test_points(
    actuator_box: Box,
    design_box: Box,
    n_train: int,
    n_test: int,
    per_design: int,
    *,
    seed: int = 0,
) -> dict[str, np.ndarray]:
    """`train_test_points` with `per_design` consecutive samples sharing one design: rows
    (actuator point, design point), the actuator points and the designs each drawn as their
    own point set (a design is meshed once for several actuations)."""
    actuations = train_test_points(actuator_box, n_train, n_test, seed=seed)
    designs = train_test_points(
        design_box, -(-n_train // per_design), -(-n_test // per_design), seed=(seed, 1)
    )
    return {
        split: np.hstack([points, np.repeat(designs[split], per_design, axis=0)[: len(points)]])
        for split, points in actuations.items()
    }
