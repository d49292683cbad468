"""The Trunk pushes a cube to three goals by inverse control with contacts (QPCC, issue 3).

    python experiments/constraints/qpcc_push.py [--seconds 4.5]

Scene `trunk_push` (pliant.robots.trunk_cube): the Trunk, base fixed, beside a 50 mm cube on
an air table (frictionless floor, viscous drag 20/s). `PushControl` sets each step the goal of
the cube's centre (at most 10 mm/s towards the target) and of the trunk's point facing the cube
(the cube's face pressed in by 2 mm, to keep the contact); `InverseControl` solves Eq. 2.15
with complementarity for the cable forces, and the contact law applies the contact forces.
Targets: the cube's start + 5, 10, then 15 mm along x, one every 1.5 s.

Two runs: the trunk-cube contact frictionless (the default scene) and with friction 0.3.
Reported per step: the cube's centre, its target, the gap between the trunk and the cube's
face, the normal force on the cube, the cable forces; per target: the error when the next one
starts. Writes experiments/results/qpcc_push.json and .png.
"""

from __future__ import annotations

import argparse
import time
import warnings
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from pliant.files import write_results  # noqa: E402
from pliant.robots.trunk_cube import PUSH_TARGETS, push_demo, trunk_push  # noqa: E402
from pliant.solvers import ImplicitEuler  # noqa: E402
from pliant.viz import save_figure

DT = 0.01
PERIOD = 1.5  # seconds per target (push_demo)


def face_gap(model, state) -> float:
    """Smallest signed distance from the trunk's nodes to the cube (< 0: inside)."""
    cube = model.rigid_bodies[0]
    cube.shape.set_pose(state.rigid_positions[0], state.rigid_rotations[0])
    return float(cube.shape.signed_distance(state.positions.reshape(-1, 3)).gap.min())


def run(friction: float, seconds: float) -> dict:
    model = trunk_push(cube_friction=friction)
    solver = ImplicitEuler(model, DT)
    state = model.rest_state()
    start = state.rigid_positions[0].copy()
    cube_index = len(model.contacts.shapes)  # the cube's index as side b of a contact
    rows = {"time": [], "cube": [], "target": [], "gap": [], "push": [], "cables": []}
    began = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        for _ in range(round(seconds / DT)):
            control = push_demo(state.time)
            state = solver.step(state, control)
            forces = state.contact_forces
            on_cube = forces.keys[:, 1] == cube_index
            rows["time"].append(state.time)
            rows["cube"].append((state.rigid_positions[0] - start).tolist())
            rows["target"].append((control.target - start).tolist())
            rows["gap"].append(face_gap(model, state))
            rows["push"].append(-float(forces.forces[on_cube, 0].sum()))  # on the cube
            rows["cables"].append(state.actuation.tolist())
    seconds_taken = time.perf_counter() - began
    cube, time_s = np.array(rows["cube"]), np.array(rows["time"])
    per_target = []
    for i, offset in enumerate(PUSH_TARGETS):
        end = min(round((i + 1) * PERIOD / DT), len(time_s)) - 1
        error = cube[end] - np.array([offset, 0.0, 0.0])
        per_target.append(
            {
                "target_x_mm": offset,
                "at_s": float(time_s[end]),
                "error_x_mm": float(error[0]),
                "error_mm": float(np.linalg.norm(error)),
            }
        )
    touching = np.array(rows["gap"]) <= 0.05
    first = int(np.argmax(touching)) if touching.any() else len(touching)
    return {
        "cube_friction": friction,
        "steps": len(time_s),
        "steps_per_s": len(time_s) / seconds_taken,
        "per_target": per_target,
        "contact_kept_fraction": float(touching[first:].mean()) if first < len(touching) else 0.0,
        "largest_gap_after_first_contact_mm": float(np.max(np.array(rows["gap"])[first:]))
        if first < len(touching)
        else None,
        "largest_cable_force": float(np.max(rows["cables"])),
        "warnings": sorted({f"{w.category.__name__}: {str(w.message)[:80]}" for w in caught}),
        "series": rows,
    }


def plot(results: list[dict], path: Path) -> None:
    fig, axes = plt.subplots(1, 3, figsize=(14, 4))
    for res in results:
        label = f"trunk-cube friction {res['cube_friction']}"
        t = np.array(res["series"]["time"])
        cube = np.array(res["series"]["cube"])
        axes[0].plot(t, cube[:, 0], label=f"cube x, {label}")
        axes[0].plot(t, cube[:, 2], "--", label=f"cube z, {label}")
        axes[1].plot(t, res["series"]["gap"], label=label)
        axes[2].plot(t, res["series"]["push"], label=label)
    target = np.array(results[0]["series"]["target"])
    axes[0].plot(np.array(results[0]["series"]["time"]), target[:, 0], "k:", label="target x")
    axes[0].set(xlabel="time (s)", ylabel="displacement (mm)", title="cube centre")
    axes[1].set(xlabel="time (s)", ylabel="gap (mm)", title="trunk to cube face", ylim=(-0.1, 0.5))
    axes[2].set(xlabel="time (s)", ylabel="force (mN)", title="normal force on the cube")
    for ax in axes:
        ax.legend(fontsize=7)
    fig.tight_layout()
    save_figure(fig, path, dpi=90)
    plt.close(fig)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=4.5)
    parser.add_argument("--out", type=Path, default=Path("experiments/results"))
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    results = [run(0.0, args.seconds), run(0.3, args.seconds)]
    for res in results:
        print(f"trunk-cube friction {res['cube_friction']}: {res['steps_per_s']:.0f} steps/s")
        for t in res["per_target"]:
            print(
                f"  target +{t['target_x_mm']:.0f} mm at {t['at_s']:.2f} s: error x"
                f" {t['error_x_mm']:+.3f} mm, |error| {t['error_mm']:.3f} mm"
            )
        print(f"  contact kept {100 * res['contact_kept_fraction']:.0f}% of the steps")
    plot(results, args.out / "qpcc_push.png")
    write_results(args.out / "qpcc_push.json", {"dt_s": DT, "runs": results})


if __name__ == "__main__":
    main()
