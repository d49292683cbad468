"""Frames of a simulated robot: its surface, cables, effectors, goals, obstacles and rigid
bodies."""

from __future__ import annotations

import numpy as np

from pliant.constraints.cable import CableActuator
from pliant.constraints.effector import RigidEffector
from pliant.model import Model, State
from pliant.viz.render import BODY_COLOR, render_scene
from pliant.viz.shapes import shape_surface

OBSTACLE_COLOR = "#b0b0b0"
RIGID_COLOR = "#e0944a"


class RobotCamera:
    """Renders states of one model with a fixed camera (bounds set from the rest shape), the
    axis of gravity drawn vertical."""

    def __init__(
        self,
        model: Model,
        *,
        view: tuple[float, float] = (20.0, -60.0),
        size: tuple[int, int] = (640, 480),
        margin: float = 0.25,
    ) -> None:
        self.model = model
        self.view = view
        self.size = size
        # Up is against gravity: its largest component's axis (z without gravity).
        # (A model of rigid bodies alone, body None, has its own gravity and no surface.)
        gravity = getattr(model.body, "gravity", getattr(model, "gravity", np.zeros(3)))
        gravity = np.asarray(gravity, dtype=float)
        self.vertical = "xyz"[int(np.argmax(np.abs(gravity)))] if np.any(gravity) else "z"
        if model.body is not None:
            rest, _ = model.body.skin(model.body.rest_positions)
        else:
            rest = np.vstack([b.shape.bounds() for b in model.rigid_bodies])
        lo, hi = rest.min(axis=0), rest.max(axis=0)
        self._centre = 0.5 * (lo + hi)
        self._floor = 0.6 * float(np.linalg.norm(hi - lo))
        for body in getattr(model, "rigid_bodies", ()):
            box = body.shape.bounds()
            lo, hi = np.minimum(lo, box[0]), np.maximum(hi, box[1])
        pad = margin * float(np.max(hi - lo))
        self.bounds = np.array([lo - pad, hi + pad])

    def _solids(self, state: State) -> list:
        """Obstacles (grey) and rigid bodies (orange) as (points, triangles, colour)."""
        solids = []
        if self.model.contacts is not None:
            for shape in self.model.contacts.shapes:
                pts, tris = shape_surface(shape, extent=self._floor, centre=self._centre)
                solids.append((pts, tris, OBSTACLE_COLOR))
        for i, body in enumerate(getattr(self.model, "rigid_bodies", ())):
            pts, tris = shape_surface(
                body.shape,
                position=state.rigid_positions[i],
                rotation=state.rigid_rotations[i],
            )
            solids.append((pts, tris, RIGID_COLOR))
        return solids

    def _effector_points(self, effector, state: State) -> np.ndarray:
        if isinstance(effector, RigidEffector):  # an object: its centre in this state
            return state.rigid_positions[self.model.rigid_bodies.index(effector.body)][None]
        return effector.position(state.positions)

    def frame(
        self, state: State, *, title: str | None = None, goals: np.ndarray | None = None
    ) -> np.ndarray:
        x = state.positions
        lines = {
            a.name: (a.polyline(x), "tab:orange")
            for a in self.model.actuators
            if isinstance(a, CableActuator)
        }
        markers = {}
        if self.model.effectors:
            markers["effector"] = (
                np.vstack([self._effector_points(e, state) for e in self.model.effectors]),
                "tab:red",
            )
        if goals is not None:
            markers["goal"] = (np.atleast_2d(goals), "tab:green")
        return render_scene(
            [
                *([] if self.model.body is None else [(*self.model.body.skin(x), BODY_COLOR)]),
                *self._solids(state),
            ],
            title=title,
            markers=markers or None,
            lines=lines or None,
            view=self.view,
            bounds=self.bounds,
            size=self.size,
            legend=False,
            vertical=self.vertical,
        )
