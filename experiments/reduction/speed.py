"""Wall-clock speed of the reduced reference Multigait against its full FEM, on a quiet host
(issue 17's goal: at least 300 steps/s at dt 0.01 with floor contact).

    OPENBLAS_NUM_THREADS=1 python experiments/reduction/speed.py [--repeats 5]

Needs the snapshots of `experiments/reduction/multigait.py --reference ... --sequences 0
--amplitude 2000,1500` in experiments/results/reduction/cache/reference/ (run that first).
Builds the reduced model of the default settings (POD 1e-3, tau 0.003), runs the hand gait
(one cycle, 360 steps, from rest) `--repeats` times and reports the median wall-clock and
CPU-time rates; the full FEM is timed over 60 steps after 20, `--repeats` times. Writes
experiments/results/reduction/speed_reference.json with the host's load average before and
after, so that a loaded measurement shows itself.
"""

from __future__ import annotations

import argparse
import json
import os
import time
import warnings
from pathlib import Path

import numpy as np

from pliant.bench import multigait_reference
from pliant.errors import ContactConvergenceWarning
from pliant.reduction import snapshots
from pliant.reduction.pipeline import build
from pliant.reduction.solver import ReducedImplicitEuler
from pliant.robots.multigait import demo_actuation
from pliant.solvers import ImplicitEuler

DT, AMPLITUDE = 0.01, (2000.0, 1500.0)


def timed(solver, state, steps: int, skip: int = 0) -> tuple[float, float]:
    """Steps per second of wall clock and of CPU time over `steps` steps after `skip`."""
    for _ in range(skip):
        state = solver.step(state, demo_actuation(state.time, amplitude=AMPLITUDE))
    clock, cpu = time.perf_counter(), time.process_time()
    for _ in range(steps):
        state = solver.step(state, demo_actuation(state.time, amplitude=AMPLITUDE))
    return steps / (time.perf_counter() - clock), steps / (time.process_time() - cpu)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--reference", type=Path, default=Path("../shared/meshes"))
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--out", type=Path, default=Path("experiments/results/reduction"))
    args = parser.parse_args()
    load_before = os.getloadavg()
    model = multigait_reference(args.reference)
    path = args.out / "cache" / "reference" / "snapshots.h5"
    positions = np.concatenate([p for _, p in snapshots.load(path, model).values()])
    reduced = build(model, positions, pod_tolerance=1e-3, tau=3e-3, tau_membrane=3e-3)
    warnings.simplefilter("ignore", ContactConvergenceWarning)
    solver = ReducedImplicitEuler(model, reduced.basis, reduced.domain, DT)
    timed(solver, solver.rest_state(), 60)  # compile and warm the caches
    runs = [timed(solver, solver.rest_state(), 360) for _ in range(args.repeats)]
    full_solver = ImplicitEuler(model, DT)
    full = [timed(full_solver, model.rest_state(), 60, skip=20) for _ in range(args.repeats)]
    wall, cpu = np.median(runs, axis=0)
    full_wall, full_cpu = np.median(full, axis=0)
    result = {
        "modes": reduced.metadata["n_modes"],
        "tets_selected": reduced.metadata["tets_selected"],
        "triangles_selected": reduced.metadata["triangles_selected"],
        "reduced_steps_per_s": float(wall),
        "reduced_steps_per_cpu_s": float(cpu),
        "reduced_runs_wall": [float(r[0]) for r in runs],
        "full_steps_per_s": float(full_wall),
        "full_steps_per_cpu_s": float(full_cpu),
        "speed_up_wall": float(wall / full_wall),
        "goal_steps_per_s": 300,
        "load_average_before": load_before,
        "load_average_after": os.getloadavg(),
        "blas_threads": os.environ.get("OPENBLAS_NUM_THREADS", "default"),
    }
    print(json.dumps(result, indent=1))
    (args.out / "speed_reference.json").write_text(json.dumps(result, indent=1))


if __name__ == "__main__":
    main()
