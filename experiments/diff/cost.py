"""What a rollout gradient costs beside the rollout, and the memory of a 1000-step Trunk.

    python experiments/diff/cost.py [--trunk-steps 1000]

For the coarse Soft Finger (1610 tetrahedra, 50 steps), the Diamond (4046, 30 steps) and the
Trunk (default mesh, `--trunk-steps` steps, two cables ramped to 10 and 5 mm without the
per-step limit, whose target depends on the state and is not differentiated): the wall time
of the forward rollout ("fresh" tangent, as the gradient needs) and of
:func:`pliant.diff.rollout_gradient` (controls, E, nu; checkpoints every ceil(sqrt(T))
steps), their ratio, the states held at once and the peak of Python-allocated memory
(tracemalloc) during the gradient. Writes experiments/results/diff/cost.json. Timings are
wall-clock on the shared 2-core machine, under other jobs' load.
"""

from __future__ import annotations

import argparse
import json
import time
import tracemalloc
from pathlib import Path

import numpy as np

from pliant import robots
from pliant.diff import PointTracking, rollout, rollout_gradient
from pliant.solvers import ImplicitEuler

ROOT = Path(__file__).resolve().parents[2]
OUT = ROOT / "experiments" / "results" / "diff" / "cost.json"
DT = 0.01


def measure(name, model, commands, n_steps) -> dict:
    ramp = np.minimum(np.arange(1, n_steps + 1) / (0.3 * n_steps), 1.0)[:, None]
    controls = ramp * commands[None, :]
    points = model.effectors[0].points if model.effectors else None
    goal = points.positions(model.body.rest_positions) + 1.0
    loss = PointTracking(points, goal, n_steps=n_steps)
    solver = ImplicitEuler(model, DT, tangent="fresh")
    rollout(model, solver, model.rest_state(), controls[:2])  # compile, analyse
    t0 = time.perf_counter()
    rollout(model, solver, model.rest_state(), controls)
    forward = time.perf_counter() - t0
    tracemalloc.start()
    t0 = time.perf_counter()
    result = rollout_gradient(
        model,
        solver,
        model.rest_state(),
        controls,
        loss,
        wrt=("controls", "young_modulus", "poisson_ratio"),
    )
    gradient = time.perf_counter() - t0
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    state_bytes = model.rest_state().positions.nbytes * 2
    row = {
        "nodes": model.body.n_nodes,
        "elements": model.body.n_elements,
        "steps": n_steps,
        "forward_s": forward,
        "gradient_s": gradient,
        "gradient_over_forward": gradient / forward,
        "solver_steps_in_gradient": result.forward_steps,
        "states_held": result.states_held,
        "peak_traced_MB": peak / 2**20,
        "all_states_would_be_MB": (n_steps + 1) * state_bytes / 2**20,
    }
    print(name, json.dumps(row))
    return row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trunk-steps", type=int, default=1000)
    args = parser.parse_args()
    out = {
        "finger": measure("finger", robots.soft_finger(), np.array([8.0, 0.0]), 50),
        "diamond": measure("diamond", robots.diamond(), np.array([10.0, 0.0, 5.0, 0.0]), 30),
        "trunk": measure(
            "trunk",
            robots.trunk(max_displacement_change=None),
            np.array([10.0, 0, 0, 0, 0, 0, 5.0, 0]),
            args.trunk_steps,
        ),
    }
    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.write_text(json.dumps(out, indent=1) + "\n")


if __name__ == "__main__":
    main()
