"""Thesis §3.4.2: OPD on SimpleMaze plans a tilt trajectory from the maze's centre to each of
its four corners; the Tripod's inverse model turns the tilts into servo angles, which, replayed
open loop on the Maze scene (the soft Tripod carrying the same maze and ball), should bring the
ball to the same corner.

The inverse model: the maze's tilt (theta_x, theta_y) against the three servo angles, linearised
about rest from the FEM (each servo turned by +-0.2 rad and the Tripod settled: central
differences), inverted per waypoint by bounded least squares (a small QP: min |J a - theta|^2 +
eps |a|^2, |a| <= cap) (thesis: the Tripod's inverse model with the maze's orientation as
effector).

    python experiments/planning/maze_corners.py [--budget 40] [--steps 50]

Writes experiments/results/planning/maze_corners.json (+ .png of the four ball paths);
resumable: finished corners are kept.
"""

from __future__ import annotations

import argparse
import json
import warnings
from pathlib import Path

import numpy as np
from scipy.optimize import lsq_linear

from pliant.envs import make
from pliant.planning import OPD, run_episode
from pliant.viz import save_figure
from pliant.viz.video import atomic_path

OUT = Path(__file__).parents[1] / "results" / "planning" / "maze_corners.json"
SUBSTEPS = 10  # 0.1 s an action in both scenes


def settle_tilt(env, angles: np.ndarray, steps: int = 10) -> np.ndarray:
    env.reset(seed=0)
    base = env.unwrapped
    for _ in range(steps):
        env.step((angles / base.max_angle).astype(np.float32))
    return base.maze_tilt()


def tripod_jacobian(delta: float = 0.2) -> np.ndarray:
    """d(theta_x, theta_y)/d(servo angles), central differences on the settled Tripod."""
    env = make("pliant/Maze-v0", action_type="continuous", substeps=SUBSTEPS)
    columns = []
    for k in range(3):
        a = np.zeros(3)
        a[k] = delta
        columns.append((settle_tilt(env, a) - settle_tilt(env, -a)) / (2 * delta))
    return np.column_stack(columns)


def servo_angles(jacobian: np.ndarray, tilt: np.ndarray, cap: float, eps: float = 1e-3):
    """Bounded least squares: min |J a - tilt|^2 + eps |a|^2 over |a| <= cap."""
    a_matrix = np.vstack([jacobian, np.sqrt(eps) * np.eye(3)])
    b = np.concatenate([tilt, np.zeros(3)])
    return lsq_linear(a_matrix, b, bounds=(-cap, cap)).x


def plan_corner(corner: int, budget: int, steps: int) -> dict:
    env = make("pliant/SimpleMaze-v0", start="centre", substeps=SUBSTEPS)
    tilts, balls = [], []

    def record(e) -> None:
        base = e.unwrapped
        tilts.append(base.tilt.target.tolist())
        balls.append(base.ball()[:2].tolist())

    report = run_episode(
        env,
        OPD(budget=budget, gamma=0.9),
        max_steps=steps,
        seed=0,
        options={"goal": corner},
        on_step=record,
    )
    base = env.unwrapped
    return {
        "reached": bool(report.terminated and not base.task.get("fallen")),
        "planning_time_s": report.wall_time,
        "decisions": len(report.actions),
        "actions": report.actions,
        "tilts": tilts[1:],
        "ball_path": balls,
        "final_distance_mm": base.task["distance"],
    }


def replay_on_tripod(tilts: list, jacobian: np.ndarray, corner: int) -> dict:
    env = make("pliant/Maze-v0", action_type="continuous", substeps=SUBSTEPS, start="centre")
    env.reset(seed=0, options={"goal": corner})
    base = env.unwrapped
    balls, angles = [base.ball()[:2].tolist()], []
    for tilt in tilts:
        a = servo_angles(jacobian, np.asarray(tilt), base.max_angle)
        angles.append(a.tolist())
        _, _, terminated, truncated, info = env.step((a / base.max_angle).astype(np.float32))
        balls.append(base.ball()[:2].tolist())
        if terminated or truncated:
            break
    return {
        "reached": bool(info.get("is_success", False)),
        "fallen": bool(info.get("fallen", False)),
        "final_distance_mm": base.task["distance"],
        "servo_angles": angles,
        "ball_path": balls,
    }


def plot(done: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(9, 4.5))
    for ax, key, title in zip(
        axes,
        ("simple_maze", "tripod"),
        ("SimpleMaze (OPD)", "Maze (Tripod, open loop)"),
        strict=True,
    ):
        for run in done["corners"]:
            path_xy = np.array(run[key]["ball_path"])
            ax.plot(path_xy[:, 0], path_xy[:, 1], label=f"corner {run['corner']}")
        ax.set_aspect("equal")
        ax.set_xlim(-30, 30)
        ax.set_ylim(-30, 30)
        ax.set_title(title)
        ax.set_xlabel("x in the maze (mm)")
    axes[0].set_ylabel("y (mm)")
    axes[1].legend(fontsize="small")
    fig.tight_layout()
    save_figure(fig, path, dpi=100)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--budget", type=int, default=40)
    parser.add_argument("--steps", type=int, default=50)
    parser.add_argument("--out", type=Path, default=OUT)
    args = parser.parse_args()
    warnings.simplefilter("ignore")
    settings = {"budget": args.budget, "steps": args.steps}
    done = json.loads(args.out.read_text()) if args.out.is_file() else {}
    if done.get("settings") != settings:
        done = {"settings": settings, "corners": []}
    if "jacobian" not in done:
        done["jacobian"] = tripod_jacobian().tolist()
    jacobian = np.array(done["jacobian"])
    for corner in range(4):
        if corner < len(done["corners"]):
            continue
        planned = plan_corner(corner, args.budget, args.steps)
        replay = replay_on_tripod(planned["tilts"], jacobian, corner)
        done["corners"].append({"corner": corner, "simple_maze": planned, "tripod": replay})
        print(
            f"corner {corner}: SimpleMaze reached {planned['reached']} in {planned['decisions']}"
            f" decisions ({planned['planning_time_s']:.1f} s); Tripod replay reached"
            f" {replay['reached']} ({replay['final_distance_mm']:.1f} mm left)",
            flush=True,
        )
        with atomic_path(args.out) as tmp:
            tmp.write_text(json.dumps(done, indent=1))
    plot(done, args.out.with_suffix(".png"))


if __name__ == "__main__":
    main()
