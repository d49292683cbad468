"""Shared by the tutorials: where they write, and the short settings CI runs them with."""

from __future__ import annotations

import os
from pathlib import Path

#: PLIANT_TUTORIAL_QUICK=1 (CI) runs every tutorial with short settings.
QUICK = os.environ.get("PLIANT_TUTORIAL_QUICK") == "1"
#: where pictures go: the docs' assets by default, elsewhere in CI.
OUT = Path(os.environ.get("PLIANT_TUTORIAL_OUT", Path(__file__).parents[1] / "docs" / "assets"))


def out(name: str) -> Path:
    path = OUT / "tutorials" / name
    path.parent.mkdir(parents=True, exist_ok=True)
    return path


def save_figure(fig, name: str) -> Path:
    """Write a Matplotlib figure as a PNG under the tutorials' pictures."""
    path = out(name)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    return path
