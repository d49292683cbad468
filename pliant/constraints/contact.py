"""Contact of a deformable body with obstacles: what the model holds, what a step detects.

A :class:`Contacts` is part of a model, like its actuators: the obstacle shapes (static, or
kinematic with a prescribed pose and twist), a friction coefficient per shape, and the points of
the body that collide (by default its surface nodes that are not fixed). Each step detects the
points within ``margin`` of a shape and adds their rows (normal, two tangents) to the
constraint space; the step's contact problem is then solved with the actuators
(:func:`pliant.constraints.friction.solve_contact`).

The margin is SOFA's alarm distance: a point is given a contact row before it touches, so that
a step cannot jump through a surface it was not told about. It must exceed the largest
distance a surface point travels towards an obstacle in one step.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence

import numpy as np

from pliant.constraints.base import EmbeddedPoints
from pliant.constraints.collision import Shape, detect, shape_velocities
from pliant.constraints.friction import ContactConstraint, check_friction
from pliant.errors import ContactError, ContactMarginWarning


class Contacts:
    """Obstacles a body touches, and the contact law with each.

    Args:
        shapes: collision shapes (Plane, Box, Sphere, Capsule, TriangleMesh), posed in the world.
        friction: Coulomb coefficient mu, one for all shapes or one per shape.
        margin: detection (alarm) distance in model units; None: 2 % of the body's bounding-box
            diagonal.
        points: the colliding points of the body; None: its surface nodes that are not fixed.
        tolerance: contact solver tolerance: the largest correction of a contact's displacement
            in a last Gauss-Seidel sweep (model length unit; 1e-7 mm by default).
        max_iterations: contact solver sweeps before a ContactConvergenceWarning.
    """

    def __init__(
        self,
        shapes: Sequence[Shape],
        *,
        friction: float | Sequence[float] = 0.0,
        margin: float | None = None,
        points: EmbeddedPoints | None = None,
        tolerance: float = 1e-7,
        max_iterations: int = 1000,
    ) -> None:
        self.shapes = list(shapes)
        if not self.shapes:
            raise ContactError("Contacts needs at least one shape")
        for shape in self.shapes:
            if not isinstance(shape, Shape):
                raise ContactError(f"not a collision shape: {shape!r}")
        self.friction = check_friction(friction, len(self.shapes))
        if margin is not None and not (math.isfinite(margin) and margin > 0):
            raise ContactError(f"the contact margin must be finite and > 0, got {margin!r}")
        if not (math.isfinite(tolerance) and tolerance > 0):
            raise ContactError(f"the contact tolerance must be finite and > 0, got {tolerance!r}")
        if max_iterations < 1:
            raise ContactError(f"max_iterations must be >= 1, got {max_iterations}")
        self.margin = margin
        self.points = points
        self.tolerance = float(tolerance)
        self.max_iterations = int(max_iterations)

    def attach(self, body) -> None:
        """Resolve the defaults against the body (called once by the Model)."""
        if self.points is None:
            surface = np.unique(body.mesh.boundary_triangles())
            moving = np.setdiff1d(surface, body.fixed_nodes)
            self.points = EmbeddedPoints.at_nodes(moving)
        if self.margin is None:
            self.margin = 0.02 * float(np.linalg.norm(np.ptp(body.rest_positions, axis=0)))
        self.check_overlap(body.rest_positions)

    def check_overlap(self, positions: np.ndarray) -> None:
        """ContactError if a colliding point starts inside a shape deeper than the margin."""
        found = detect(self.points.positions(positions), self.shapes, self.margin)
        if len(found) and found.gap.min() < -self.margin:
            i = int(np.argmin(found.gap))
            raise ContactError(
                f"the body overlaps shape {int(found.index_b[i])} at the start: a point lies"
                f" {-found.gap[i]:.3g} inside it (more than the margin {self.margin:.3g});"
                " move the body or the shape"
            )

    def check_travel(self, displacement: np.ndarray, step: int) -> None:
        """Warn when a colliding point moved further than the margin over a step."""
        travel = float(np.linalg.norm(self.points.positions(displacement), axis=1).max())
        if travel > self.margin:
            warnings.warn(
                f"step {step}: a colliding point moved {travel:.3g}, more than the contact"
                f" margin {self.margin:.3g}; contacts may have been missed: raise the margin"
                " or reduce the time step",
                ContactMarginWarning,
                stacklevel=3,
            )

    def constraint(self, positions: np.ndarray, dt: float | None) -> ContactConstraint | None:
        """The contact rows at `positions`, or None when no point is within the margin.

        `dt`: the step, to carry moving obstacles' displacement (None: static solve).
        """
        found = detect(self.points.positions(positions), self.shapes, self.margin)
        if len(found) == 0:
            return None
        motion = None if dt is None else dt * shape_velocities(found, self.shapes)
        return ContactConstraint(
            found,
            self.points,
            friction=self.friction[found.index_b],
            obstacle_displacement=motion,
        )
