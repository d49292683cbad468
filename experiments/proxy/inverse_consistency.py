"""Which volumes would bring the FEM Multigait onto each proxy's points? (session 40)

Along the FEM's hand gait (the calibration's trajectory, dt 0.01 s), at the middle and the end
of each of its 18 actions, the FEM's state is rolled out 0.1 s under its volumes held and under
each chamber's volume nudged by 5 % of its hand-gait volume: the Jacobian J of the underside
points (the calibration's matched points) in the volumes. For each proxy, its skinned points
p at the same instant give the volume change that brings the FEM nearest them, linearised and
bounded as the transfer's actuation is ([0, 1.067] of the hand-gait volume): the bounded least
squares min ||J x - (p - p_FEM)||^2 + eps ||x||^2 (the QP's relative eps 1e-3), the points'
mean offset along the floor taken out (the travel is not the inverse model's to correct). A
proxy whose shapes the FEM reaches with the volumes the proxy was commanded has x = 0.

    python experiments/proxy/inverse_consistency.py

Writes experiments/results/proxy/inverse_consistency.json (each proxy's x per instant, in
fractions of the hand-gait volumes, and its means). About 3 minutes on one core.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
from scipy.optimize import lsq_linear

from pliant.files import write_json
from pliant.proxy.builders import MULTIGAIT_PARAMETERS
from pliant.proxy.calibrate import fitted_proxy
from pliant.proxy.references import multigait_reference, setup
from pliant.robots.multigait import _face_nodes, chamber_amplitudes, demo_actuation, multigait
from pliant.solvers import ImplicitEuler

OUT = Path("experiments/results/proxy/inverse_consistency.json")
CALIBRATIONS = Path("experiments/proxy")
PROXIES = {
    "cross": CALIBRATIONS / "cross/multigait_calibration.json",
    "surface": CALIBRATIONS / "surface/multigait-joint_calibration.json",
    "joint": CALIBRATIONS / "joint/multigait-joint_calibration.json",
    "travel": CALIBRATIONS / "travel/multigait-joint_calibration.json",
    "underside": CALIBRATIONS / "underside/multigait-joint_calibration.json",
}
HOLD, NUDGE, UPPER = 10, 0.05, 1.067  # steps held, nudge and bound (fractions of the volume)


def fem_jacobians(steps: int = 1080, dt: float = 0.01) -> dict:
    """The FEM's underside points and their Jacobian in the volumes at the sampled instants."""
    model = multigait(mesh_size=6.0)
    nodes = _face_nodes(model.body.mesh, 10.0)
    amplitude = chamber_amplitudes()
    solver, state = ImplicitEuler(model, dt), model.rest_state()
    samples = set(range(29, steps, 30))
    out = {"step": [], "volumes": [], "points": [], "jacobian": []}

    def roll(start, volumes):
        for _ in range(HOLD):
            start = solver.step(start, volumes)
        return start.positions[nodes].ravel()

    for k in range(steps):
        volumes = demo_actuation(state.time)
        state = solver.step(state, volumes)
        if k not in samples:
            continue
        held = roll(state.copy(), volumes)
        jacobian = np.empty((held.size, volumes.size))
        for j in range(volumes.size):
            h = NUDGE * amplitude[j] * (1.0 if volumes[j] < amplitude[j] else -1.0)
            moved = volumes.copy()
            moved[j] += h
            jacobian[:, j] = (roll(state.copy(), moved) - held) / h
        out["step"].append(k)
        out["volumes"].append(volumes)
        out["points"].append(held.reshape(-1, 3))
        out["jacobian"].append(jacobian)
    return {key: np.array(value) for key, value in out.items()} | {"amplitude": amplitude}


def consistency(fem: dict, points: np.ndarray) -> np.ndarray:
    """(n, 5) the bounded volume changes, over the hand-gait volumes, at the sampled instants
    (`points`: the proxy's (T, K, 3) along the reference)."""
    amplitude = fem["amplitude"]
    rows = []
    for i, k in enumerate(fem["step"]):
        gap = points[k] - fem["points"][i]
        gap[:, :2] -= gap[:, :2].mean(axis=0)
        jacobian, volumes = fem["jacobian"][i], fem["volumes"][i]
        eps = 1e-3 * float(np.sum(jacobian**2)) / volumes.size
        rows_ = np.vstack([jacobian, np.sqrt(eps) * np.eye(volumes.size)])
        rhs = np.concatenate([gap.ravel(), np.zeros(volumes.size)])
        bounds = (-volumes, UPPER * amplitude - volumes)
        rows.append(lsq_linear(rows_, rhs, bounds=bounds).x / amplitude)
    return np.array(rows)


def main() -> None:
    fem = fem_jacobians()
    reference = multigait_reference()
    simulate = setup("multigait").simulate(reference)
    proxies = {"defaults": dict(MULTIGAIT_PARAMETERS)}
    for name, path in PROXIES.items():
        proxies[name] = fitted_proxy(json.loads(path.read_text()))
    result = {
        "command": "python experiments/proxy/inverse_consistency.py " + " ".join(sys.argv[1:])
    }
    result["instants_s"] = [round((k + 1) * reference.dt, 2) for k in fem["step"]]
    result["commands"] = [np.round(v / fem["amplitude"], 3).tolist() for v in fem["volumes"]]
    result["proxies"] = {}
    for name, parameters in proxies.items():
        points = simulate(parameters)
        change = consistency(fem, points)
        error = float(np.linalg.norm(points - reference.points, axis=-1).mean())
        result["proxies"][name] = {
            "parameters": parameters,
            "points_error_mm": round(error, 3),
            "mean_abs_change": round(float(np.abs(change).mean()), 3),
            "mean_abs_change_per_chamber": np.round(np.abs(change).mean(axis=0), 3).tolist(),
            "mean_change_per_chamber": np.round(change.mean(axis=0), 3).tolist(),
            "change": np.round(change, 3).tolist(),
        }
        print(
            f"{name}: points {error:.2f} mm, mean |change| {np.abs(change).mean():.3f},"
            f" per chamber {np.round(np.abs(change).mean(axis=0), 3)}",
            flush=True,
        )
    write_json(OUT, result)


if __name__ == "__main__":
    main()
