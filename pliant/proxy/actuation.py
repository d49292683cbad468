"""Actuation of a beam-skeleton proxy: commands in [-1, 1] that set the rest curvature of
groups of rod elements (thesis Eq. 4.1: the pre-curvature alpha_{b,t} of beam b).

A pneumatic cavity becomes one actuated bending of its beam, three or more cables around a
slender part two (thesis §4.1.1). The rod's forces and tangents read its rest curvature at
each step, so the static and dynamic solvers need nothing more: call :meth:`apply` between
steps.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from pliant.errors import ModelError
from pliant.fem.rod import RodBody


@dataclass(frozen=True)
class Bending:
    """One actuated bending: command u moves the rest curvature of `elements` by
    u * max_curvature along `axis` (material frame: d1, d2 bendings, d3 twist; unit), and
    their rest stretch by u * max_stretch - |u| * max_contraction.

    The stretch is for a skeleton that does not lie on the neutral layer of what it bends: a
    pneumatic chamber bends its leg about the strain-limiting layer under it, so that a
    skeleton at height h over that layer lengthens by kappa h as it curls
    (``multigait_proxy(neutral="underside")``); a beam bent about its own axis keeps its
    length (max_stretch 0). The contraction is for a beam shortened by what bends it,
    whichever way: a cable-driven trunk's cables compress it along its axis as they curl it
    (the FEM Trunk's centreline 5 % shorter with its long cable pulled 20 mm).

    Args:
        name: the actuator's name ("front_left", "lower_d1").
        elements: indices of the rod's elements bent together (one beam).
        axis: (3,) direction of the curvature in the elements' material frames.
        max_curvature: curvature (rad per length) at command 1.
        max_stretch: axial rest strain at command 1 (0.1: 10 % longer).
        max_contraction: axial rest shortening at command +-1 (0.05: 5 % shorter).
    """

    name: str
    elements: tuple[int, ...]
    axis: tuple[float, float, float]
    max_curvature: float
    max_stretch: float = 0.0
    max_contraction: float = 0.0


class CurvatureActuation:
    """The bendings of one rod, applied together: kappa0 = natural + sum_b u_b k_b axis_b,
    and the rest stretch natural + sum_b (u_b s_b - |u_b| c_b) (where some bending stretches
    or contracts).

    Args:
        rod: the proxy's skeleton.
        bendings: its actuated bendings, in command order.
    """

    def __init__(self, rod: RodBody, bendings: Sequence[Bending]) -> None:
        self.rod = rod
        self.bendings = tuple(bendings)
        for b in self.bendings:
            idx = np.asarray(b.elements, dtype=np.int64)
            if idx.size == 0 or idx.min() < 0 or idx.max() >= rod.n_elements:
                raise ModelError(f"bending {b.name}: elements must lie in [0, {rod.n_elements})")
            if abs(float(np.linalg.norm(b.axis)) - 1.0) > 1e-9:
                raise ModelError(f"bending {b.name}: the axis must be a unit vector")
            if not (np.isfinite(b.max_stretch) and abs(b.max_stretch) < 1.0):
                raise ModelError(f"bending {b.name}: the max stretch must lie in (-1, 1)")
            if not (np.isfinite(b.max_contraction) and 0.0 <= b.max_contraction < 1.0):
                raise ModelError(f"bending {b.name}: the max contraction must lie in [0, 1)")
        self.stretches = any(b.max_stretch != 0.0 or b.max_contraction for b in self.bendings)
        self.controls = np.zeros(len(self.bendings))

    @property
    def names(self) -> list[str]:
        return [b.name for b in self.bendings]

    def __len__(self) -> int:
        return len(self.bendings)

    def apply(self, controls: Sequence[float]) -> None:
        """Set the rest curvature for commands `controls` (one per bending, in [-1, 1])."""
        u = np.asarray(controls, dtype=float).reshape(-1)
        if u.shape != (len(self.bendings),) or not np.all(np.isfinite(u)):
            raise ModelError(f"expected {len(self.bendings)} finite commands, got {controls!r}")
        if np.abs(u).max(initial=0.0) > 1.0 + 1e-12:
            raise ModelError(f"bending commands must lie in [-1, 1], got {u.tolist()}")
        kappa = self.rod.natural_curvature.copy()
        for b, value in zip(self.bendings, u, strict=True):
            kappa[list(b.elements)] += value * b.max_curvature * np.asarray(b.axis)
        self.rod.set_rest_curvature(kappa)
        if self.stretches:
            stretch = self.rod.natural_strain[:, 2].copy()
            for b, value in zip(self.bendings, u, strict=True):
                stretch[list(b.elements)] += value * b.max_stretch - abs(value) * b.max_contraction
            self.rod.set_rest_stretch(stretch)
        self.controls = u.copy()


class ProxySolver:
    """A solver of a proxy with Pliant's one solver interface: ``step(state, control)``
    applies the commands as the proxy's rest curvatures (and base) and steps `solver`, so
    that controllers and environments drive a proxy as they drive a FEM robot. Everything
    else (dt, model, system) is the wrapped solver's."""

    def __init__(self, proxy, solver) -> None:
        self.proxy = proxy
        self.solver = solver

    def step(self, state, control=None):
        if control is not None:
            self.proxy.apply(control)
        return self.solver.step(state)

    def __getattr__(self, name: str):
        return getattr(self.solver, name)
