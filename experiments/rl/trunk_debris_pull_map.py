"""TrunkSpaceDebris: where does the whole-arm pull catch, with the long cables' course at 35
and at 40 mm? (issue #16; the thesis draws its cubes "within the grasping capabilities of the
Trunk robot", and this maps them for the one program that catches.)

    PYTHONPATH=. python experiments/rl/trunk_debris_pull_map.py

On a grid of placements (cube 25, 30, 35, 40 mm x centre height 65-125 mm x gap 10, 15, 20 mm
from the trunk's surface, straight out along +x), plays ``pliant.envs.trunk_space_debris:
expert`` (the long +x cable pulled 2 mm a step to the end of its course and held) once for
each course and scores it by the catch test (opposite faces pressed, the cube off the hull,
the last 5 steps). Writes experiments/results/rl/trunk_debris_pull_map.json (rewritten
atomically after each course; a rerun skips the courses done) and .png (one panel a course
and gap: catches over size and height).
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from experiments.rl.trunk_debris_pull import episode
from pliant.envs import make
from pliant.envs.trunk_space_debris import expert
from pliant.files import write_json
from pliant.robots.trunk_debris import beside_trunk
from pliant.viz import save_figure

RESULTS = Path("experiments/results/rl/trunk_debris_pull_map")
SIZES = (25.0, 30.0, 35.0, 40.0)
HEIGHTS = (65.0, 75.0, 85.0, 95.0, 105.0, 115.0, 125.0)
GAPS = (10.0, 15.0, 20.0)
COURSES = (35.0, 40.0)  # the environment's long course, and five millimetres more


def play(course: float) -> list[dict]:
    env = make(
        "pliant/TrunkSpaceDebris-v0",
        continuous_mode="increment",
        success="catch",
        cube_sizes=list(SIZES),
        max_long_displacement=course,
    )
    records = []
    for size in SIZES:
        for z in HEIGHTS:
            for gap in GAPS:
                position = beside_trunk(size, z, gap, 0.0)
                obs, _ = env.reset(seed=0, options={"cube_size": size, "cube_position": position})
                outcome = episode(env, expert(env), obs)
                records.append({"cube_size": size, "z": z, "gap": gap, **outcome})
    env.close()
    return records


def plot(summary: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    courses = sorted(summary["courses"], key=float)
    fig, axes = plt.subplots(
        len(courses), len(GAPS), figsize=(3.2 * len(GAPS), 2.8 * len(courses)), squeeze=False
    )
    for row, course in enumerate(courses):
        records = summary["courses"][course]["placements"]
        for col, gap in enumerate(GAPS):
            grid = np.zeros((len(SIZES), len(HEIGHTS)))
            for r in records:
                if r["gap"] == gap:
                    grid[SIZES.index(r["cube_size"]), HEIGHTS.index(r["z"])] = r["catch"]
            ax = axes[row, col]
            ax.imshow(grid, cmap="Greens", vmin=0, vmax=1, origin="lower", aspect="auto")
            ax.set_xticks(range(len(HEIGHTS)), [f"{h:g}" for h in HEIGHTS], fontsize=7)
            ax.set_yticks(range(len(SIZES)), [f"{s:g}" for s in SIZES], fontsize=7)
            ax.set_title(f"course {float(course):g} mm, gap {gap:g} mm", fontsize=8)
            if col == 0:
                ax.set_ylabel("cube (mm)")
            if row == len(courses) - 1:
                ax.set_xlabel("height of the cube's centre (mm)")
    fig.suptitle("whole-arm pull: catches (green) by placement", fontsize=9)
    fig.tight_layout()
    save_figure(fig, path, dpi=110)
    plt.close(fig)


def main() -> None:
    import json

    path = RESULTS.with_suffix(".json")
    summary = json.loads(path.read_text()) if path.exists() else {"courses": {}}
    summary["command"] = "PYTHONPATH=. python experiments/rl/trunk_debris_pull_map.py"
    for course in COURSES:
        key = f"{course:g}"
        if key in summary["courses"]:
            continue
        clock = time.perf_counter()
        records = play(course)
        by_size = {
            f"{s:g}": int(sum(r["catch"] for r in records if r["cube_size"] == s)) for s in SIZES
        }
        summary["courses"][key] = {
            "catches": int(sum(r["catch"] for r in records)),
            "placements_tried": len(records),
            "catches_by_cube_size": by_size,
            "diverged": int(sum(r["diverged"] for r in records)),
            "lost": int(sum(r["lost"] for r in records)),
            "wall_seconds": time.perf_counter() - clock,
            "placements": records,
        }
        write_json(path, summary)
        print(key, summary["courses"][key]["catches"], by_size, flush=True)
    plot(summary, RESULTS.with_suffix(".png"))


if __name__ == "__main__":
    main()
