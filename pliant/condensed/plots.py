"""Figures of the learned condensed model: trajectories reached with learned and exact
matrices (thesis Fig. 5.4), training curves."""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from pliant.viz.render import offscreen_figure
from pliant.viz.video import atomic_path

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
    ax_err.set_xlabel("goal index")
    ax_err.set_ylabel(f"distance to goal [{unit}]")
    ax_err.set_ylim(bottom=0.0)
    ax_err.grid(True, alpha=0.3)
    ax_err.legend()
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=150)
    return Path(path)


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
    if title:
        ax.set_title(title)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=150)
    return Path(path)
