"""Table 4.1 on this machine: real-time factor (simulated s per wall s) of the FEM robots and
of their beam-skeleton proxies at dt = 0.01, 0.02, 0.03 s, each under its demo actuation (the
Multigait's gait; the Trunk bending onto the cube while its base moves).

    python experiments/proxy/speed.py [--steps 40] [--out experiments/results/proxy_speed.json]
    python experiments/proxy/speed.py --reference --out experiments/results/proxy_speed_ref.json

Timed after a warm-up of 5 steps (numba compilation excluded). Thesis (Table 4.1, dt 0.01):
proxy 250x faster than the FEM for the Multigait, 3x for the Trunk, proxy RTF 0.57 / 0.62.
``--reference`` times the thesis' Multigait instead: SoftRobots' mesh (../shared/meshes), its
full FEM, its reduced model (31 modes, from the snapshots that experiments/reduction/speed.py
uses, in experiments/results/reduction/cache/reference/) and the proxy, side by side, under
the gait of amplitude (2000, 1500) mm^3.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

import numpy as np

from pliant.bench import multigait_reference
from pliant.proxy import multigait_proxy, trunk_proxy
from pliant.proxy.actuation import ProxySolver
from pliant.robots.multigait import demo_actuation as gait
from pliant.robots.multigait import multigait
from pliant.robots.trunk_cube import demo_actuation as trunk_demo
from pliant.robots.trunk_cube import demo_base_motion, trunk_cube
from pliant.solvers import ImplicitEuler

AMPLITUDE = np.array([4900.0, 3300.0, 3300.0, 3300.0, 3300.0])  # the gait's volumes


def trunk_proxy_commands(t: float) -> np.ndarray:
    """The FEM demo's counterpart: bend the trunk towards +x (onto the cube) over 1 s,
    advance the base 20 mm between 1 s and 2 s."""
    bend = min(t, 1.0)
    return np.array([0.0, 0.5 * bend, 0.0, 0.5 * bend, -demo_base_motion(t)])


CASES = {
    "multigait_fem": (multigait, gait, None),
    "multigait_proxy": (
        lambda: multigait_proxy(),
        lambda t: gait(t) / AMPLITUDE,
        True,
    ),
    "trunk_fem": (trunk_cube, trunk_demo, None),
    "trunk_proxy": (lambda: trunk_proxy(), trunk_proxy_commands, True),
    # the proxies touching through the FEM's skinned surface (contact="surface")
    "multigait_proxy_surface": (
        lambda: multigait_proxy(contact="surface"),
        lambda t: gait(t) / AMPLITUDE,
        True,
    ),
    "trunk_proxy_surface": (lambda: trunk_proxy(contact="surface"), trunk_proxy_commands, True),
}


def reference_gait(t: float) -> np.ndarray:
    return gait(t, amplitude=REFERENCE_AMPLITUDE)


REFERENCE_AMPLITUDE = (2000.0, 1500.0)
REFERENCE_CASES = {
    "multigait_reference_fem": "full",
    "multigait_reference_reduced": "reduced",
    "multigait_proxy": "proxy",
}


def reference_solver(kind: str, dt: float):
    """(solver, state, commands) of the thesis' Multigait: full FEM, reduced or proxy."""
    if kind == "proxy":
        robot = multigait_proxy()
        solver = ProxySolver(robot, ImplicitEuler(robot.model, dt))
        scale = np.array([REFERENCE_AMPLITUDE[0]] + [REFERENCE_AMPLITUDE[1]] * 4)
        return solver, robot.model.rest_state(), lambda t: reference_gait(t) / scale
    model = multigait_reference(Path("../shared/meshes"))
    if kind == "full":
        return ImplicitEuler(model, dt), model.rest_state(), reference_gait
    import warnings

    from pliant.errors import ContactConvergenceWarning
    from pliant.reduction import snapshots
    from pliant.reduction.pipeline import build
    from pliant.reduction.solver import ReducedImplicitEuler

    cache = Path("experiments/results/reduction/cache/reference/snapshots.h5")
    positions = np.concatenate([p for _, p in snapshots.load(cache, model).values()])
    reduced = build(model, positions, pod_tolerance=1e-3, tau=3e-3, tau_membrane=3e-3)
    warnings.simplefilter("ignore", ContactConvergenceWarning)
    solver = ReducedImplicitEuler(model, reduced.basis, reduced.domain, dt)
    return solver, solver.rest_state(), reference_gait


def real_time_factor(case: str, dt: float, steps: int) -> float:
    if case in REFERENCE_CASES:
        solver, state, commands = reference_solver(REFERENCE_CASES[case], dt)
    else:
        build, commands, is_proxy = CASES[case]
        robot = build()
        model = robot.model if is_proxy else robot
        solver = ImplicitEuler(model, dt)
        if is_proxy:
            solver = ProxySolver(robot, solver)
        state = model.rest_state()
    for _ in range(5):
        state = solver.step(state, commands(state.time))
    start = time.perf_counter()
    for _ in range(steps):
        state = solver.step(state, commands(state.time))
    return steps * dt / (time.perf_counter() - start)


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--steps", type=int, default=40)
    parser.add_argument("--cases", nargs="*", default=None)
    parser.add_argument("--reference", action="store_true", help="the thesis' Multigait")
    parser.add_argument("--out", type=Path, default=Path("experiments/results/proxy_speed.json"))
    args = parser.parse_args()
    cases = args.cases or list(REFERENCE_CASES if args.reference else CASES)
    load_before = os.getloadavg()
    table = {}
    for case in cases:
        for dt in (0.01, 0.02, 0.03):
            table[f"{case}@{dt}"] = rtf = real_time_factor(case, dt, args.steps)
            print(f"{case:16s} dt {dt:.2f}  RTF {rtf:8.3f}", flush=True)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    result = {"steps": args.steps, "real_time_factor": table}
    result["load_average_before_after"] = [load_before, os.getloadavg()]
    args.out.write_text(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
