"""How far the lagged tangent moves a trajectory, beside implicit Euler's own time error.

    python experiments/solvers/lagged_tangent.py [--meshes ../shared/meshes]

The SoftRobots Diamond (4 cables) and Trunk (8 cables) are pulled by commands ramped over
0.3 s and simulated for 1.5 s. Reference: the "fresh" tangent (refactorised every step, as
SOFA does) at dt / 4. Reported per run: the largest nodal distance to the reference over the
trajectory (compared every 0.01 s) and at the end, and the factorisations. Writes
experiments/results/lagged_tangent.json and .png.
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from pliant import robots  # noqa: E402
from pliant.bench import reference_diamond  # noqa: E402
from pliant.mesh import load_mesh  # noqa: E402
from pliant.solvers import ImplicitEuler  # noqa: E402
from pliant.viz import save_figure  # noqa: E402

DT, RAMP, DURATION = 0.01, 0.3, 1.5


def scenes(meshes: Path):
    yield "diamond", robots.diamond(mesh=reference_diamond(meshes)), np.full(4, 10.0)
    trunk = robots.trunk(mesh=load_mesh(meshes / "Trunk_trunk.vtk"))
    yield "trunk", trunk, np.array([10.0, 0, 0, 0, 0, 0, 5.0, 0])


def trajectory(model, command, dt: float, tangent: str, lag_tolerance: float | None = None):
    """Positions every 0.01 s, and the number of factorisations."""
    solver = ImplicitEuler(model, dt, tangent=tangent)
    if lag_tolerance is not None:
        solver.system.lag_tolerance = lag_tolerance
    state = model.rest_state()
    every = round(DT / dt)
    frames = []
    for i in range(round(DURATION / dt)):
        state = solver.step(state, command * min(1.0, (i + 1) * dt / RAMP))
        if (i + 1) % every == 0:
            frames.append(state.positions.copy())
    return np.array(frames), solver.system.factorisations


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--meshes", type=Path, default=Path("../shared/meshes"))
    parser.add_argument("--out", type=Path, default=Path("experiments/results/lagged_tangent"))
    args = parser.parse_args()
    results = {}
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.6))
    for ax, (name, model, command) in zip(axes, scenes(args.meshes), strict=True):
        reference, _ = trajectory(model, command, DT / 4, "fresh")
        rest = model.rest_state().positions
        runs = {
            "fresh, dt": ("fresh", DT, None),
            "fresh, dt/2": ("fresh", DT / 2, None),
            "lagged 0.01, dt": ("lagged", DT, 0.01),
            "lagged 0.02 (default), dt": ("lagged", DT, 0.02),
        }
        results[name] = {"max_motion_mm": float(np.abs(reference - rest).max()), "runs": {}}
        for label, (tangent, dt, tol) in runs.items():
            frames, facts = trajectory(model, command, dt, tangent, tol)
            dev = np.abs(frames - reference).max(axis=(1, 2))
            results[name]["runs"][label] = {
                "max_deviation_mm": float(dev.max()),
                "final_deviation_mm": float(dev[-1]),
                "factorisations": int(facts),
                "steps": round(DURATION / dt),
            }
            ax.semilogy(np.arange(1, dev.size + 1) * DT, dev, label=label)
            print(f"{name:8s} {label:26s} max {dev.max():.3g} mm, end {dev[-1]:.3g} mm", facts)
        ax.set_title(f"{name}: distance to fresh at dt/4")
        ax.set_xlabel("time (s)")
        ax.set_ylabel("max nodal distance (mm)")
        ax.legend(fontsize=7)
    fig.tight_layout()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    save_figure(fig, args.out.with_suffix(".png"), dpi=110)
    fd, tmp = tempfile.mkstemp(dir=args.out.parent, suffix=".json")
    with os.fdopen(fd, "w") as fh:
        payload = {"dt": DT, "ramp_s": RAMP, "duration_s": DURATION, "scenes": results}
        json.dump(payload, fh, indent=1)
    os.replace(tmp, args.out.with_suffix(".json"))


if __name__ == "__main__":
    main()
