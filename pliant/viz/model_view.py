"""Frames of a simulated robot: its surface, cables, effectors and goals."""

from __future__ import annotations

import numpy as np

from pliant.constraints.cable import CableActuator
from pliant.model import Model, State
from pliant.viz.render import render_frame


class RobotCamera:
    """Renders states of one model with a fixed camera (bounds set from the rest shape)."""

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
        self.triangles = model.body.mesh.boundary_triangles()
        rest = model.body.rest_positions
        lo, hi = rest.min(axis=0), rest.max(axis=0)
        pad = margin * float(np.max(hi - lo))
        self.bounds = np.array([lo - pad, hi + pad])

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
                np.vstack([e.position(x) for e in self.model.effectors]),
                "tab:red",
            )
        if goals is not None:
            markers["goal"] = (np.atleast_2d(goals), "tab:green")
        return render_frame(
            x,
            self.triangles,
            title=title,
            markers=markers or None,
            lines=lines or None,
            view=self.view,
            bounds=self.bounds,
            size=self.size,
            legend=False,
        )
