"""Regenerate the gallery's pictures: every registered robot after its scripted demo's first
second (`python docs/gen_gallery.py`; `--quick` for a smoke run into a temporary folder)."""

from __future__ import annotations

import sys
import warnings
from pathlib import Path

from pliant import robots
from pliant.scenario import scripted
from pliant.solvers import ImplicitEuler
from pliant.viz import save_png
from pliant.viz.model_view import RobotCamera

#: simulated seconds shown per robot (the demos' interesting moment).
SHOW = {"multigait": 1.8, "trunk_push": 1.0, "gripper": 2.5, "simple_maze": 1.5, "tripod_maze": 1.5}


def summary(entry) -> str:
    """The first paragraph of the demo's docstring, on one line."""
    doc = (entry.demo_actuation.__doc__ or "").strip().split("\n\n")[0]
    return " ".join(doc.split())


def page(names: list[str]) -> str:
    rows = [
        "# Gallery\n",
        "Every registered robot and scene after the first moments of its scripted demo. Each",
        "runs with `pliant run NAME` (a GIF, a PNG and a ParaView series in `out/NAME/`).",
        "Regenerate the pictures with `python docs/gen_gallery.py`.\n",
    ]
    for name in names:
        entry = robots.ROBOTS[name]
        rows += [
            f"## `{name}`\n",
            f"![{name}](assets/gallery/{name}.png)\n",
            f"`pliant run {name}`: {summary(entry)}\n",
        ]
    return "\n".join(rows)


def main(out: Path, quick: bool) -> None:
    names = sorted(robots.ROBOTS)
    (out.parent.parent if not quick else out).mkdir(parents=True, exist_ok=True)
    (out.parent.parent / "gallery.md" if not quick else out / "gallery.md").write_text(page(names))
    for name in names:
        entry = robots.ROBOTS[name]
        model = entry.build()
        sim = ImplicitEuler(model, dt=0.01)
        steps = 2 if quick else round(SHOW.get(name, 1.0) / 0.01)
        state = model.rest_state()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            for state in scripted(sim, model.rest_state(), entry.demo_actuation, steps):  # noqa: B007
                pass
        camera = RobotCamera(model, view=entry.view, size=(480, 360))
        save_png(camera.frame(state, title=f"{name}  t = {state.time:.1f} s"), out / f"{name}.png")
        print(name)


if __name__ == "__main__":
    quick = "--quick" in sys.argv
    main(Path(sys.argv[-1]) if quick else Path(__file__).parent / "assets" / "gallery", quick)
