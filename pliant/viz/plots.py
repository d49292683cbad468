"""Report figures: reaching trajectories, timing scaling, convergence under refinement.

Each function draws on its own offscreen `Figure` (no pyplot state) and writes a PNG
atomically, returning the path written.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from pliant.viz.render import apply_camera, offscreen_figure, scene_bounds
from pliant.viz.video import save_figure

_MARKERS = ("o", "s", "^", "D", "v", "P", "X")
_DPI = 150


def _save(fig: Figure, path: str | os.PathLike) -> Path:
    save_figure(fig, path, dpi=_DPI)
    return Path(path)


def _positive_series(name: str, xs: np.ndarray, ys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    xs, ys = np.asarray(xs, dtype=float).ravel(), np.asarray(ys, dtype=float).ravel()
    if xs.shape != ys.shape or xs.size == 0:
        raise ValueError(
            f"series {name!r}: x and y must be non-empty and of equal length, "
            f"got {xs.size} and {ys.size}"
        )
    if not (np.all(np.isfinite(xs) & (xs > 0)) and np.all(np.isfinite(ys) & (ys > 0))):
        raise ValueError(f"series {name!r}: a log-log plot needs finite positive values")
    return xs, ys


def _draw_loglog(ax: Axes, series: Mapping[str, tuple[np.ndarray, np.ndarray]]) -> None:
    for i, (name, (xs, ys)) in enumerate(series.items()):
        xs, ys = _positive_series(name, xs, ys)
        order = np.argsort(xs)
        ax.loglog(xs[order], ys[order], marker=_MARKERS[i % len(_MARKERS)], label=name)
    ax.grid(True, which="both", alpha=0.3)


def convergence_order(hs: np.ndarray, errors: np.ndarray) -> float:
    """Least-squares slope p of log(error) = p log(h) + c: the observed order of convergence."""
    hs, errors = _positive_series("errors", hs, errors)
    if hs.size < 2:
        raise ValueError("a convergence order needs at least two mesh sizes")
    return float(np.polyfit(np.log(hs), np.log(errors), 1)[0])


def plot_trajectory(
    goals: np.ndarray,
    reached: np.ndarray,
    path: str | os.PathLike,
    *,
    title: str | None = None,
    unit: str = "mm",
) -> Path:
    """Goals against reached effector positions in 3D, and the distance between them per goal.

    Args:
        goals: (k, 3) target positions, in order.
        reached: (k, 3) positions the effector reached for each goal.
        path: PNG file to write.
        title: figure title.
        unit: length unit for the labels.
    """
    goals = np.asarray(goals, dtype=float).reshape(-1, 3)
    reached = np.asarray(reached, dtype=float).reshape(-1, 3)
    if goals.shape != reached.shape or len(goals) == 0:
        raise ValueError(
            f"goals and reached must both be (k, 3) with k > 0, got {goals.shape} and "
            f"{reached.shape}"
        )
    error = np.linalg.norm(reached - goals, axis=1)

    fig = offscreen_figure(11.0, 4.8)
    ax3 = fig.add_subplot(1, 2, 1, projection="3d")
    apply_camera(ax3, scene_bounds([goals, reached]), view=(25.0, -60.0))
    ax3.set_proj_type("persp")
    ax3.plot(*goals.T, color="tab:red", marker="x", linestyle=":", label="goal")
    ax3.plot(*reached.T, color="tab:blue", marker="o", markersize=3, label="reached")
    for g, r in zip(goals, reached, strict=True):
        ax3.plot(*np.stack([g, r]).T, color="0.6", linewidth=0.8)
    ax3.set_xlabel(f"x [{unit}]")
    ax3.set_ylabel(f"y [{unit}]")
    ax3.set_zlabel(f"z [{unit}]")
    ax3.legend(loc="upper left")

    ax = fig.add_subplot(1, 2, 2)
    ax.plot(np.arange(len(error)), error, marker="o", markersize=3, color="tab:blue")
    ax.axhline(error.mean(), color="0.4", linestyle="--", label=f"mean {error.mean():.3g} {unit}")
    goal_distance_axes(ax, unit)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return _save(fig, path)


def goal_distance_axes(ax: Axes, unit: str) -> None:
    """Labels, grid and legend of a panel of the distance to the goal per goal index."""
    ax.set_xlabel("goal index")
    ax.set_ylabel(f"distance to goal [{unit}]")
    ax.set_ylim(bottom=0.0)
    ax.grid(True, alpha=0.3)
    ax.legend()


def _finish_axes(fig, ax, path, xlabel: str, ylabel: str, title: str | None) -> Path:
    """Legend, labels and title on one axes, then the figure written to `path`."""
    ax.legend()
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    if title:
        ax.set_title(title)
    fig.tight_layout()
    return _save(fig, path)


def plot_loglog(
    series: Mapping[str, tuple[np.ndarray, np.ndarray]],
    path: str | os.PathLike,
    *,
    xlabel: str,
    ylabel: str,
    title: str | None = None,
) -> Path:
    """Several named (xs, ys) series on log-log axes, each with its own marker.

    Example: steps per second against element count for Pliant and SOFA,
    `plot_loglog({"Pliant": (n, rate_p), "SOFA": (n, rate_s)}, "speed.png",
    xlabel="elements", ylabel="steps / s")`.
    """
    if not series:
        raise ValueError("plot_loglog needs at least one series")
    fig = offscreen_figure(6.4, 4.8)
    ax = fig.add_subplot(1, 1, 1)
    _draw_loglog(ax, series)
    return _finish_axes(fig, ax, path, xlabel, ylabel, title)


def plot_convergence(
    hs: np.ndarray,
    errors: np.ndarray | Mapping[str, np.ndarray],
    path: str | os.PathLike,
    *,
    expected_order: float | None = None,
    xlabel: str = "mesh size h",
    ylabel: str = "error",
    title: str | None = None,
) -> Path:
    """Error against mesh size on log-log axes, each series labelled with its fitted order.

    Args:
        hs: (r,) mesh sizes.
        errors: (r,) errors, or several named error series (e.g. L2 and energy norm).
        path: PNG file to write.
        expected_order: if given, a dashed reference line h^p through the first series'
            value at the coarsest mesh.
        xlabel, ylabel, title: labels.
    """
    hs = np.asarray(hs, dtype=float).ravel()
    named = dict(errors) if isinstance(errors, Mapping) else {"error": errors}
    if not named:
        raise ValueError("plot_convergence needs at least one error series")
    series = {
        f"{name} (order {convergence_order(hs, e):.2f})": (hs, e) for name, e in named.items()
    }
    fig = offscreen_figure(6.4, 4.8)
    ax = fig.add_subplot(1, 1, 1)
    _draw_loglog(ax, series)
    if expected_order is not None:
        first = np.asarray(next(iter(named.values())), dtype=float).ravel()
        coarsest = int(np.argmax(hs))
        ref = first[coarsest] * (hs / hs[coarsest]) ** expected_order
        order = np.argsort(hs)
        ax.loglog(
            hs[order], ref[order], "--", color="0.3", label=f"$h^{{{expected_order:g}}}$", zorder=3
        )
    return _finish_axes(fig, ax, path, xlabel, ylabel, title)
