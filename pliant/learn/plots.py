"""Learning curves of a run folder (evaluations.json, episodes.csv) as a PNG."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np

from pliant.viz import save_figure


def plot_learning_curve(run_dir: Path, out: Path | None = None, title: str | None = None) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    run_dir = Path(run_dir)
    out = out or run_dir / "learning_curve.png"
    curve = json.loads((run_dir / "evaluations.json").read_text())
    steps = [e["step"] for e in curve]
    has_success = any(e.get("success_rate") is not None for e in curve)
    fig, axes = plt.subplots(1, 2 if has_success else 1, figsize=(10 if has_success else 5, 3.6))
    axes = np.atleast_1d(axes)
    ax = axes[0]
    episodes = run_dir / "episodes.csv"
    if episodes.exists():
        with open(episodes) as f:
            rows = list(csv.DictReader(f))
        if rows:
            x = np.array([float(r["step"]) for r in rows])
            y = np.array([float(r["return"]) for r in rows])
            window = max(1, len(y) // 50)
            smooth = np.convolve(y, np.ones(window) / window, mode="valid")
            ax.plot(x[window - 1 :], smooth, color="0.6", lw=1, label="training episodes")
    ax.plot(steps, [e["mean_return"] for e in curve], "o-", label="evaluation (deterministic)")
    ax.set_xlabel("environment steps")
    ax.set_ylabel("episode return")
    ax.legend(fontsize=8)
    if has_success:
        axes[1].plot(steps, [100 * (e.get("success_rate") or 0.0) for e in curve], "o-")
        axes[1].set_xlabel("environment steps")
        axes[1].set_ylabel("evaluation success (%)")
        axes[1].set_ylim(-2, 102)
    fig.suptitle(title or run_dir.name)
    fig.tight_layout()
    save_figure(fig, out, dpi=110)
    plt.close(fig)
    return out
