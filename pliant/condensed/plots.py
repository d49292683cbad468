"""Figures of the learned condensed model: trajectories reached with learned and exact
matrices (thesis Fig. 5.4, 5.9), forces reached (Fig. 5.8), training curves, calibration
histories (Fig. 5.13), design landscapes, refinements and Pareto front (Fig. 5.15-5.17)."""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from pliant.viz.plots import goal_distance_axes
from pliant.viz.render import offscreen_figure
from pliant.viz.video import save_figure

if TYPE_CHECKING:
    from pliant.condensed.design import DesignStudy

_AXES = "xyz"


def plot_reached(
    goals: np.ndarray,
    reached: Mapping[str, np.ndarray],
    path: str | os.PathLike,
    *,
    plane: tuple[int, int] = (0, 1),
    title: str | None = None,
    unit: str = "mm",
) -> Path:
    """Goals and the effector positions each controller reached, projected on a plane, beside
    the distance to the goal per goal (Fig. 5.4).

    Args:
        goals: (n, 3).
        reached: controller name -> (n, 3) reached positions.
        plane: the two axes drawn, (0, 1) for (x, y).
    """
    goals = np.asarray(goals, dtype=float).reshape(-1, 3)
    fig = offscreen_figure(11.0, 4.8)
    ax, ax_err = fig.add_subplot(1, 2, 1), fig.add_subplot(1, 2, 2)
    i, j = plane
    ax.plot(goals[:, i], goals[:, j], "o", color="tab:orange", label="goal")
    for (name, points), marker in zip(reached.items(), ("x", "+", "1", "2"), strict=False):
        points = np.asarray(points, dtype=float).reshape(-1, 3)
        ax.plot(points[:, i], points[:, j], marker, markersize=8, label=name)
        error = np.linalg.norm(points - goals, axis=1)
        ax_err.plot(error, marker="o", markersize=3, label=f"{name}: mean {error.mean():.3g}")
    ax.set_xlabel(f"{_AXES[i]} [{unit}]")
    ax.set_ylabel(f"{_AXES[j]} [{unit}]")
    ax.set_aspect("equal", adjustable="datalim")
    ax.legend()
    goal_distance_axes(ax_err, unit)
    return _save(fig, path, title=title)


def plot_forces(
    requested: np.ndarray,
    reached: Mapping[str, np.ndarray],
    path: str | os.PathLike,
    *,
    title: str | None = None,
    unit: str = "mN",
) -> Path:
    """Forces reached against the forces requested, one marker set per controller, beside the
    relative error per request (the button of Fig. 5.8 in force)."""
    requested = np.asarray(requested, dtype=float)
    fig = offscreen_figure(11.0, 4.8)
    ax, ax_err = fig.add_subplot(1, 2, 1), fig.add_subplot(1, 2, 2)
    ax.plot(requested, requested, "-", color="tab:orange", linewidth=1, label="requested")
    for (name, forces), marker in zip(reached.items(), ("x", "+", "1", "2"), strict=False):
        forces = np.asarray(forces, dtype=float)
        ax.plot(requested, forces, marker, markersize=8, label=name)
        error = np.abs(forces - requested) / requested
        ax_err.semilogy(
            requested, error, marker="o", markersize=3, label=f"{name}: max {error.max():.2g}"
        )
    ax.set_xlabel(f"requested [{unit}]")
    ax.set_ylabel(f"reached in the FEM [{unit}]")
    ax.legend()
    ax_err.set_xlabel(f"requested [{unit}]")
    ax_err.set_ylabel("|reached - requested| / requested")
    ax_err.grid(True, alpha=0.3)
    ax_err.legend()
    return _save(fig, path, title=title)


def plot_history(history: list[dict], path: str | os.PathLike, *, title: str | None = None) -> Path:
    """Train and test loss (Eq. 5.5, standardised) per epoch, log scale."""
    epochs = [h["epoch"] for h in history]
    fig = offscreen_figure(6.4, 4.2)
    ax = fig.add_subplot(1, 1, 1)
    for key in ("train", "test"):
        ax.semilogy(epochs, [h[key] for h in history], label=key)
    best = min(history, key=lambda h: h["test"])
    ax.plot(best["epoch"], best["test"], "o", color="k", label=f"best {best['test']:.3g}")
    ax.set_xlabel("epoch")
    ax.set_ylabel("standardised loss")
    ax.grid(True, alpha=0.3)
    ax.legend()
    return _save(fig, path, title=title, ax=ax)


def plot_calibration(
    runs: Mapping[str, list[dict]],
    parameter: str,
    path: str | os.PathLike,
    *,
    truth: float | None = None,
    title: str | None = None,
) -> Path:
    """Calibration histories (Fig. 5.13): O_cal (Eq. 5.15) and the fitted parameter per
    iteration, one line per start."""
    fig = offscreen_figure(11.0, 4.2)
    ax_obj, ax_par = fig.add_subplot(1, 2, 1), fig.add_subplot(1, 2, 2)
    for label, history in runs.items():
        iterations = [h["iteration"] for h in history]
        ax_obj.semilogy(iterations, [h["objective"] for h in history], label=label)
        ax_par.plot(iterations, [h[parameter] for h in history], label=label)
    if truth is not None:
        ax_par.axhline(truth, color="k", linestyle="--", linewidth=1, label=f"truth {truth:g}")
    ax_obj.set_xlabel("iteration")
    ax_obj.set_ylabel("O_cal [mm]")
    ax_par.set_xlabel("iteration")
    ax_par.set_ylabel(parameter)
    for ax in (ax_obj, ax_par):
        ax.grid(True, alpha=0.3)
        ax.legend()
    return _save(fig, path, title=title)


def plot_design_study(study: DesignStudy, folder: str | os.PathLike) -> list[Path]:
    """Fig. 5.15-5.17: landscapes around the starts, refinement histories, Pareto front."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    names = study.names
    paths = []

    fig = offscreen_figure(13.0, 7.6)
    for row, (objective, maps) in enumerate(study.landscapes.items()):
        best = study.refined[objective].design
        for col, ((i, j), a, b, values) in enumerate(maps):
            ax = fig.add_subplot(len(study.landscapes), len(maps), row * len(maps) + col + 1)
            image = ax.contourf(a, b, values.T, levels=20, cmap="viridis")
            fig.colorbar(image, ax=ax)
            ax.plot(best[i], best[j], "o", color="tab:blue", markeredgecolor="w")
            ax.set_xlabel(f"{names[i]} [mm]")
            ax.set_ylabel(f"{names[j]} [mm]")
            ax.set_title(f"O_{objective}", fontsize=9)
    fig.suptitle("objective landscapes around the grid's best (dot: refined design)")
    paths.append(_save(fig, folder / "landscapes.png", dpi=130))

    fig = offscreen_figure(13.0, 3.8 * len(study.refined))
    for row, (objective, result) in enumerate(study.refined.items()):
        iterations = [h["iteration"] for h in result.history]
        ax = fig.add_subplot(len(study.refined), 2, 2 * row + 1)
        ax.plot(iterations, [h["objective"] for h in result.history])
        ax.set_ylabel(f"O_{objective}")
        ax.grid(True, alpha=0.3)
        ax = fig.add_subplot(len(study.refined), 2, 2 * row + 2)
        for name in names:
            ax.plot(iterations, [h[name] for h in result.history], label=name)
        ax.set_ylabel("design [mm]")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8)
    for ax in fig.axes[-2:]:
        ax.set_xlabel("iteration")
    paths.append(_save(fig, folder / "refinement.png", dpi=130))

    fig = offscreen_figure(6.4, 5.0)
    ax = fig.add_subplot(1, 1, 1)
    dex = _normalised(study.dexterity)
    strength = _normalised(study.strength)
    ax.scatter(dex, strength, s=8, c="0.6", label=f"grid ({len(dex)} designs)")
    front = study.pareto
    order = np.argsort(dex[front])
    ax.plot(dex[front][order], strength[front][order], "o-", color="tab:red", label="Pareto")
    ax.set_xlabel("O_dext normalised")
    ax.set_ylabel("O_str normalised")
    ax.grid(True, alpha=0.3)
    ax.legend()
    paths.append(_save(fig, folder / "pareto.png", dpi=150))
    return paths


def _save(
    fig, path: str | os.PathLike, *, dpi: int = 150, title: str | None = None, ax=None
) -> Path:
    """Title the figure (or `ax`) if `title`, lay it out and write it as a PNG, atomically."""
    if title:
        (fig.suptitle if ax is None else ax.set_title)(title)
    fig.tight_layout()
    save_figure(fig, path, dpi=dpi)
    return Path(path)


def _normalised(values: np.ndarray) -> np.ndarray:
    """(O - min) / (max - min) over the grid (the normalisation of Eq. 5.20)."""
    span = values.max() - values.min()
    return (values - values.min()) / (span if span > 0 else 1.0)
