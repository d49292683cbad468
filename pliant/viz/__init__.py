"""Offscreen rendering, report plots and video/ParaView output (Matplotlib Agg, no display)."""

from pliant.viz.plots import convergence_order, plot_convergence, plot_loglog, plot_trajectory
from pliant.viz.render import (
    DEFAULT_VIEW,
    Surface,
    draw_scene,
    render_frame,
    render_scene,
    render_surface,
    scene_bounds,
)
from pliant.viz.video import VtuSeriesWriter, atomic_path, save_figure, save_gif, save_png

__all__ = [
    "DEFAULT_VIEW",
    "Surface",
    "VtuSeriesWriter",
    "atomic_path",
    "convergence_order",
    "draw_scene",
    "plot_convergence",
    "plot_loglog",
    "plot_trajectory",
    "render_frame",
    "render_scene",
    "render_surface",
    "save_figure",
    "save_gif",
    "save_png",
    "scene_bounds",
]
