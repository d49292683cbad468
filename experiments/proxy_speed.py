"""Table 4.1 on this machine: real-time factor (simulated s per wall s) of the FEM robots and
of their beam-skeleton proxies at dt = 0.01, 0.02, 0.03 s, each under its demo actuation (the
Multigait's gait; the Trunk bending onto the cube while its base moves).

    python experiments/proxy_speed.py [--steps 40] [--out experiments/results/proxy_speed.json]

Timed after a warm-up of 5 steps (numba compilation excluded). Thesis (Table 4.1, dt 0.01):
proxy 250x faster than the FEM for the Multigait, 3x for the Trunk, proxy RTF 0.57 / 0.62.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

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
}


def real_time_factor(case: str, dt: float, steps: int) -> float:
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
    parser.add_argument("--cases", nargs="*", default=list(CASES))
    parser.add_argument("--out", type=Path, default=Path("experiments/results/proxy_speed.json"))
    args = parser.parse_args()
    table = {}
    for case in args.cases:
        for dt in (0.01, 0.02, 0.03):
            table[f"{case}@{dt}"] = rtf = real_time_factor(case, dt, args.steps)
            print(f"{case:16s} dt {dt:.2f}  RTF {rtf:8.3f}", flush=True)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"steps": args.steps, "real_time_factor": table}, indent=2))


if __name__ == "__main__":
    main()
