"""The condensed (compliance) problem: W and delta_free in the constraint space (Eq. 2.14)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pliant.errors import ConstraintError


@dataclass(frozen=True)
class CondensedProblem:
    """delta = W lambda + delta_free for all constraint rows, at one step.

    W_ij = H_i A^-1 H_j^T (dynamic step, A scaled to map forces to displacements over the
    step: W = h^2 H (M + h D + h^2 K)^-1 H^T) or H_i K^-1 H_j^T (static). Rows are ordered
    actuators, effectors, contacts; `slices` gives each block.
    """

    compliance: np.ndarray
    free_distance: np.ndarray
    slices: dict[str, slice]

    @classmethod
    def of_rows(
        cls,
        compliance: np.ndarray,
        free_distance: np.ndarray,
        *,
        actuators: int = 0,
        effectors: int = 0,
    ) -> CondensedProblem:
        """The problem whose first `actuators` rows are actuators', the next `effectors`
        effectors' and the rest contacts'."""
        r, e = free_distance.size, actuators + effectors
        slices = {
            "actuator": slice(0, actuators),
            "effector": slice(actuators, e),
            "contact": slice(e, r),
        }
        return cls(compliance, free_distance, slices)

    def block(self, row: str, col: str) -> np.ndarray:
        """W_{row,col}, e.g. block("effector", "actuator") is W_ea."""
        return self.compliance[self._rows(row), self._rows(col)]

    def free(self, role: str) -> np.ndarray:
        """delta_free of one role."""
        return self.free_distance[self._rows(role)]

    def _rows(self, role: str) -> slice:
        try:
            return self.slices[role]
        except (KeyError, TypeError):
            raise ConstraintError(
                f"no constraint role {role!r}; the roles are {', '.join(map(repr, self.slices))}"
            ) from None

    @property
    def n_actuators(self) -> int:
        s = self.slices["actuator"]
        return s.stop - s.start
