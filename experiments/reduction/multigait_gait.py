"""How far the hand-defined gait (thesis §3.4.1) moves the Multigait, with and without its
paper membrane, and with no actuation.

    python experiments/reduction/multigait_gait.py [--cycles 3] [--mesh-size 6] \
        [--centre 4900] [--legs 3300]

The default Pliant Multigait (parametric mesh, paper membrane under it, volume-controlled
chambers, floor, friction 0.7) runs `cycles` gait cycles of six phases (rear legs, centre,
front legs inflated, then deflated in that order); then the same gait without the membrane,
and the same time with no actuation. Reported: the x travel of the centre of mass every step,
and after each phase also of the front and rear ends of the underside, the highest chamber
pressure, the contacts in use, and steps/s. Forward is -x (towards the front legs, away from
the legs inflated first). Writes experiments/results/multigait_gait.json and .png.
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
import time
import warnings
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from pliant.errors import ContactConvergenceWarning  # noqa: E402
from pliant.robots.multigait import centre_of_mass, demo_actuation, multigait  # noqa: E402
from pliant.solvers import ImplicitEuler  # noqa: E402
from pliant.viz import save_figure

DT = 0.01


def walk(model, amplitude: tuple[float, float], phase: float, cycles: int) -> dict:
    """Travel along x every step (centre of mass) and after each phase (centre of mass, front
    and rear ends of the underside), chamber pressures, contacts, and steps/s."""
    solver = ImplicitEuler(model, DT)
    state = model.rest_state()
    underside = np.flatnonzero(model.body.rest_positions[:, 2] < 1e-9)

    def where(x: np.ndarray) -> np.ndarray:
        """Centre of mass, front end and rear end of the underside, along x."""
        return np.array([centre_of_mass(model, x)[0], x[underside, 0].min(), x[underside, 0].max()])

    start = where(state.positions)
    per_phase = round(phase / DT)
    travel, ends, contacts, pressure = [], [], [], 0.0
    began = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ContactConvergenceWarning)
        for step in range(6 * cycles * per_phase):
            command = demo_actuation(state.time, amplitude=amplitude, phase=phase)
            state = solver.step(state, command)
            travel.append(round(float(centre_of_mass(model, state.positions)[0] - start[0]), 4))
            pressure = max(pressure, float(state.actuation.max(initial=0.0)))
            if (step + 1) % per_phase == 0:
                ends.append(np.round(where(state.positions) - start, 4).tolist())
                contacts.append(len(state.contact_forces.keys))
    seconds = time.perf_counter() - began
    per_cycle = np.diff([[0.0, 0.0, 0.0], *ends[5::6]], axis=0)
    return {
        "amplitude": list(amplitude),
        "travel_mm": travel,
        "after_phase_mm": {
            name: [e[k] for e in ends] for k, name in enumerate(("com", "front", "rear"))
        },
        "travel_per_cycle_mm": np.round(per_cycle[:, 0], 3).tolist(),
        "front_per_cycle_mm": np.round(per_cycle[:, 1], 3).tolist(),
        "rear_per_cycle_mm": np.round(per_cycle[:, 2], 3).tolist(),
        "max_pressure_kPa": round(pressure, 2),
        "contacts_after_phase": contacts,
        "steps_per_s": len(travel) / seconds,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cycles", type=int, default=3)
    parser.add_argument("--mesh-size", type=float, default=6.0)
    parser.add_argument("--centre", type=float, default=4900.0, help="mm^3 of growth")
    parser.add_argument("--legs", type=float, default=3300.0, help="mm^3 of growth per leg")
    parser.add_argument("--phase", type=float, default=0.6)
    parser.add_argument("--out", type=Path, default=Path("experiments/results/multigait_gait"))
    args = parser.parse_args()
    model = multigait(mesh_size=args.mesh_size)
    amplitude = (args.centre, args.legs)
    runs = {
        "gait": walk(model, amplitude, args.phase, args.cycles),
        "gait, no membrane": walk(
            multigait(mesh_size=args.mesh_size, membrane_stiffness=0.0),
            amplitude,
            args.phase,
            args.cycles,
        ),
        "no actuation": walk(model, (0.0, 0.0), args.phase, args.cycles),
    }
    results = {
        "mesh_size": args.mesh_size,
        "tetrahedra": int(model.body.mesh.n_tets),
        "membrane_triangles": len(model.body.membranes[0].membrane.triangles),
        "contact_points": len(model.contacts.points),
        "phase_s": args.phase,
        "dt_s": DT,
        "cycles": args.cycles,
        "runs": runs,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.NamedTemporaryFile("w", dir=args.out.parent, delete=False) as tmp:
        json.dump(results, tmp, indent=1)
    os.replace(tmp.name, args.out.with_suffix(".json"))

    fig, ax = plt.subplots(figsize=(7, 3.5))
    for name, run in runs.items():
        t = DT * np.arange(1, len(run["travel_mm"]) + 1)
        ax.plot(t, run["travel_mm"], label=name)
    for k in range(1, args.cycles):
        ax.axvline(6 * args.phase * k, color="0.8", lw=0.8)
    ax.set_xlabel("time (s); grey lines: gait cycles")
    ax.set_ylabel("centre of mass travel along x (mm)\n(forward is -x)")
    ax.set_title(f"Multigait, {results['tetrahedra']} tetrahedra, phase {args.phase} s")
    ax.legend()
    fig.tight_layout()
    save_figure(fig, args.out.with_suffix(".png"), dpi=100)
    for name, run in runs.items():
        per_cycle = ", ".join(f"{d:+.2f}" for d in run["travel_per_cycle_mm"])
        print(
            f"{name}: {per_cycle} mm per cycle, up to {run['max_pressure_kPa']:.1f} kPa,"
            f" {run['steps_per_s']:.1f} steps/s"
        )


if __name__ == "__main__":
    main()
