"""Figures of an optimised trajectory: effector positions and velocities beside their goals,
actuation beside its bounds (thesis Fig. 5.20-5.22)."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from pliant.viz.video import save_figure


def plot_trajectory(
    times: np.ndarray,
    runs: dict[str, tuple[np.ndarray, np.ndarray]],
    goals: np.ndarray | dict[str, np.ndarray],
    bounds: tuple[np.ndarray, np.ndarray],
    path: str | os.PathLike,
    *,
    title: str = "",
    units: tuple[str, str, str] = ("mm", "mm/s", "mN"),
    relative: bool = False,
) -> Path:
    """One column per run (name -> (xs (N + 1, 2m), us (N, n_a))): positions with the goals
    (dashed; one array for every run, or one per run's name), velocities, actuation with its
    bounds (dotted). `relative`: positions and goals less the start's, so that a few mm of
    motion show beside coordinates of 100 mm."""
    fig = Figure(figsize=(5.0 * len(runs), 8.0))
    axes = fig.subplots(3, len(runs), squeeze=False, sharex=True)
    colours = ("tab:red", "tab:green", "tab:blue", "tab:purple", "tab:orange", "tab:brown")
    for col, (name, (xs, us)) in enumerate(runs.items()):
        m = xs.shape[1] // 2
        run_goals = goals[name] if isinstance(goals, dict) else goals
        origin = xs[0, :m] if relative else np.zeros(m)
        ax_p, ax_v, ax_u = axes[:, col]
        for i in range(m):
            c = colours[i % len(colours)]
            ax_p.plot(
                times, xs[:, i] - origin[i], color=c, label="xyz"[i % 3] if m <= 3 else f"p{i}"
            )
            ax_p.plot(times, run_goals[:, i] - origin[i], color=c, linestyle="--", linewidth=0.8)
            ax_v.plot(times, xs[:, m + i], color=c)
        for j in range(us.shape[1]):
            ax_u.step(times[:-1], us[:, j], where="post", label=f"u{j}")
        for bound in bounds:
            for b in np.unique(bound[np.isfinite(bound)]):
                ax_u.axhline(b, color="k", linestyle=":", linewidth=0.8)
        ax_p.set_title(name)
        ax_p.set_ylabel(f"position{' - start' if relative else ''} ({units[0]})")
        ax_v.set_ylabel(f"velocity ({units[1]})")
        ax_u.set_ylabel(f"actuation ({units[2]})")
        ax_u.set_xlabel("time (s)")
        ax_p.legend(fontsize=7)
        ax_u.legend(fontsize=7)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    save_figure(fig, path, dpi=120)
    return Path(path)
