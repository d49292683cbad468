"""How far the hand-defined gait (thesis §3.4.1) moves the Multigait, and with zero pressure.

    python experiments/multigait_gait.py [--cycles 3] [--mesh-size 6] [--pressure 30]

The default Pliant Multigait (parametric mesh, floor, friction 0.7) runs `cycles` gait cycles
of six phases (rear legs, centre, front legs inflated, then deflated in that order), and the
same time with all chambers at zero pressure. Reported: the x travel of the centre of mass
after each phase and each cycle, the contacts in use, and steps/s. Writes
experiments/results/multigait_gait.json and .png.
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

DT = 0.01


def walk(model, pressure: float, phase: float, cycles: int) -> dict:
    """Centre-of-mass travel along x every step, contacts after each phase, and steps/s."""
    solver = ImplicitEuler(model, DT)
    state = model.rest_state()
    start = centre_of_mass(model, state.positions)[0]
    per_phase = round(phase / DT)
    travel, contacts = [], []
    began = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ContactConvergenceWarning)
        for step in range(6 * cycles * per_phase):
            state = solver.step(state, demo_actuation(state.time, pressure=pressure, phase=phase))
            travel.append(float(centre_of_mass(model, state.positions)[0] - start))
            if (step + 1) % per_phase == 0:
                contacts.append(len(state.contact_forces.keys))
    seconds = time.perf_counter() - began
    ends = [travel[(k + 1) * per_phase - 1] for k in range(6 * cycles)]
    return {
        "pressure_kPa": pressure,
        "travel_mm": travel,
        "travel_after_phase_mm": ends,
        "travel_per_cycle_mm": np.diff([0.0, *ends[5::6]]).tolist(),
        "contacts_after_phase": contacts,
        "steps_per_s": len(travel) / seconds,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cycles", type=int, default=3)
    parser.add_argument("--mesh-size", type=float, default=6.0)
    parser.add_argument("--pressure", type=float, default=30.0)
    parser.add_argument("--phase", type=float, default=0.6)
    parser.add_argument("--out", type=Path, default=Path("experiments/results/multigait_gait"))
    args = parser.parse_args()
    model = multigait(mesh_size=args.mesh_size)
    runs = {
        "gait": walk(model, args.pressure, args.phase, args.cycles),
        "zero pressure": walk(model, 0.0, args.phase, args.cycles),
    }
    results = {
        "mesh_size": args.mesh_size,
        "tetrahedra": int(model.body.mesh.n_tets),
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
        ax.plot(t, run["travel_mm"], label=f"{name} ({run['pressure_kPa']:g} kPa)")
    for k in range(1, args.cycles):
        ax.axvline(6 * args.phase * k, color="0.8", lw=0.8)
    ax.set_xlabel("time (s); grey lines: gait cycles")
    ax.set_ylabel("centre of mass travel along x (mm)")
    ax.set_title(f"Multigait, {results['tetrahedra']} tetrahedra, phase {args.phase} s")
    ax.legend()
    fig.tight_layout()
    fig.savefig(args.out.with_suffix(".png"), dpi=100)
    for name, run in runs.items():
        per_cycle = ", ".join(f"{d:+.2f}" for d in run["travel_per_cycle_mm"])
        print(f"{name}: {per_cycle} mm per cycle, {run['steps_per_s']:.1f} steps/s")


if __name__ == "__main__":
    main()
