"""Losses of a trajectory, stage by stage, with their gradients.

A rollout of T steps has states s_0 .. s_T and controls c_0 .. c_{T-1}; a loss is a sum of
stage terms l_n(s_n, c_{n-1}) (no control at n = 0). Written stage by stage, a loss can be
evaluated again on the states a checkpointed reverse sweep recomputes, without keeping the
trajectory.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from pliant.constraints.base import EmbeddedPoints
from pliant.errors import ModelError
from pliant.model import State


@dataclass
class StageGradient:
    """A stage term's value and gradients (None where it does not depend on that input):
    positions and velocities (n, 3), control (n_a,)."""

    value: float
    positions: np.ndarray | None = None
    velocities: np.ndarray | None = None
    control: np.ndarray | None = None


class Loss(Protocol):
    """A trajectory loss as a sum of stage terms."""

    def stage(self, n: int, state: State, control: np.ndarray | None) -> StageGradient:
        """The term of stage n (0..T) at state s_n, reached by control c_{n-1} (None at 0)."""
        ...


class PointTracking:
    """0.5 weight |p_n - target_n|^2 summed over points (embedded in the body: nodes, an
    effector's points) and over the stages `stages` (default all, "final" for the last).
    With ``quantity="velocities"`` p_n is the points' velocity (the same barycentric sum of
    the nodes' velocities), e.g. a velocity penalty with zero targets.

    Args:
        points: the tracked points, e.g. ``model.effectors[0].points``.
        targets: (k, 3) for every stage, or (T + 1, k, 3) one per stage.
        weight: the term's weight.
        stages: "all", "final", or the stage indices.
        n_steps: T, needed for "final" and checked against per-stage targets.
        quantity: "positions" or "velocities" of the points.
    """

    def __init__(
        self,
        points: EmbeddedPoints,
        targets: np.ndarray,
        *,
        n_steps: int,
        weight: float = 1.0,
        stages: str | list[int] = "all",
        quantity: str = "positions",
    ) -> None:
        if quantity not in ("positions", "velocities"):
            raise ModelError(f"quantity must be 'positions' or 'velocities', got {quantity!r}")
        self.quantity = quantity
        self.points = points
        self.targets = np.asarray(targets, dtype=float)
        k = len(points)
        if self.targets.shape not in ((k, 3), (n_steps + 1, k, 3)):
            raise ModelError(
                f"targets must be ({k}, 3) or ({n_steps + 1}, {k}, 3), got {self.targets.shape}"
            )
        self.weight = float(weight)
        if stages == "all":
            self.stages = set(range(n_steps + 1))
        elif stages == "final":
            self.stages = {n_steps}
        else:
            self.stages = set(int(s) for s in stages)

    def target(self, n: int) -> np.ndarray:
        return self.targets if self.targets.ndim == 2 else self.targets[n]

    def stage(self, n: int, state: State, control: np.ndarray | None) -> StageGradient:
        if n not in self.stages:
            return StageGradient(0.0)
        values = getattr(state, self.quantity)
        residual = self.points.positions(values) - self.target(n)
        grad = np.zeros_like(values)
        spread = self.weight * self.points.weights[:, :, None] * residual[:, None, :]
        np.add.at(grad, self.points.nodes, spread)
        return StageGradient(
            0.5 * self.weight * float(np.sum(residual**2)), **{self.quantity: grad}
        )


class ControlPenalty:
    """0.5 weight |c_n|^2 over every step's control (effort regularisation)."""

    def __init__(self, weight: float) -> None:
        self.weight = float(weight)

    def stage(self, n: int, state: State, control: np.ndarray | None) -> StageGradient:
        if control is None:
            return StageGradient(0.0)
        return StageGradient(
            0.5 * self.weight * float(control @ control), control=self.weight * control
        )


class Losses:
    """The sum of several losses."""

    def __init__(self, *terms: Loss) -> None:
        self.terms = terms

    def stage(self, n: int, state: State, control: np.ndarray | None) -> StageGradient:
        total = StageGradient(0.0)
        for term in self.terms:
            part = term.stage(n, state, control)
            total.value += part.value
            for name in ("positions", "velocities", "control"):
                mine, theirs = getattr(total, name), getattr(part, name)
                if theirs is not None:
                    setattr(total, name, theirs if mine is None else mine + theirs)
        return total


class StateCotangents:
    """The linear loss sum_n <dq_n, q_n> + <dv_n, v_n> for given cotangents (T + 1, n, 3)
    (with `points`, of the points' positions, (T + 1, k, 3)): the vector-Jacobian product of
    a trajectory, what a torch backward pass hands over."""

    def __init__(
        self,
        positions: np.ndarray,
        velocities: np.ndarray | None = None,
        *,
        points: EmbeddedPoints | None = None,
    ) -> None:
        self.positions = np.asarray(positions, dtype=float)
        self.velocities = None if velocities is None else np.asarray(velocities, dtype=float)
        self.points = points

    def stage(self, n: int, state: State, control: np.ndarray | None) -> StageGradient:
        if self.points is not None:
            value = float(np.sum(self.positions[n] * self.points.positions(state.positions)))
            grad = np.zeros_like(state.positions)
            spread = self.points.weights[:, :, None] * self.positions[n][:, None, :]
            np.add.at(grad, self.points.nodes, spread)
            return StageGradient(value, positions=grad)
        value = float(np.sum(self.positions[n] * state.positions))
        dv = None
        if self.velocities is not None:
            dv = self.velocities[n]
            value += float(np.sum(dv * state.velocities))
        return StageGradient(value, positions=self.positions[n], velocities=dv)
