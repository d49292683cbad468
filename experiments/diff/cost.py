"""What a rollout gradient costs beside the rollout, and the memory of a 1000-step Trunk.

    python experiments/diff/cost.py [--trunk-steps 1000]

For the coarse Soft Finger (1610 tetrahedra, 50 steps), the Diamond (4046, 30 steps) and the
Trunk (default mesh, `--trunk-steps` steps, two cables ramped to 10 and 5 mm over the first
30 %): the wall time of the forward rollout ("fresh" tangent, as the gradient needs) and of
:func:`pliant.diff.rollout_gradient` (controls, E, nu), keeping every state and with
checkpoints every ceil(sqrt(T)) steps, their ratio to the forward rollout, the states held
at once, and for the Trunk the peak of Python-allocated memory (tracemalloc, a separate
run). Writes experiments/results/diff/cost.json. Timings are wall-clock on the shared 2-core
machine, under other jobs' load.
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


def measure(name, model, commands, n_steps, *, memory: bool = False) -> dict:
    ramp = np.minimum(np.arange(1, n_steps + 1) / (0.3 * n_steps), 1.0)[:, None]
    controls = ramp * commands[None, :]
    points = model.effectors[0].points
    goal = points.positions(model.body.rest_positions) + 1.0
    loss = PointTracking(points, goal, n_steps=n_steps)
    solver = ImplicitEuler(model, DT, tangent="fresh")
    wrt = ("controls", "young_modulus", "poisson_ratio")
    rollout_gradient(model, solver, model.rest_state(), controls[:2], loss, wrt=wrt)  # compile
    t0 = time.perf_counter()
    rollout(model, solver, model.rest_state(), controls)
    forward = time.perf_counter() - t0
    row = {
        "nodes": model.body.n_nodes,
        "elements": model.body.n_elements,
        "steps": n_steps,
        "forward_s": forward,
    }
    sqrt_k = int(np.ceil(np.sqrt(n_steps)))
    for label, every in (("all_states_kept", None), ("checkpoints_sqrt_T", sqrt_k)):
        t0 = time.perf_counter()
        result = rollout_gradient(
            model, solver, model.rest_state(), controls, loss, wrt=wrt, checkpoint_every=every
        )
        wall = time.perf_counter() - t0
        row[label] = {
            "gradient_s": wall,
            "gradient_over_forward": wall / forward,
            "solver_steps": result.forward_steps,
            "states_held": result.states_held,
        }
        if memory:  # again under tracemalloc (which slows allocation: not timed)
            tracemalloc.start()
            rollout_gradient(
                model, solver, model.rest_state(), controls, loss, wrt=wrt, checkpoint_every=every
            )
            row[label]["peak_traced_MB"] = tracemalloc.get_traced_memory()[1] / 2**20
            tracemalloc.stop()
    row["state_MB"] = 2 * model.rest_state().positions.nbytes / 2**20
    print(name, json.dumps(row), flush=True)
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
            robots.trunk(),
            np.array([10.0, 0, 0, 0, 0, 0, 5.0, 0]),
            args.trunk_steps,
            memory=True,
        ),
    }
    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.write_text(json.dumps(out, indent=1) + "\n")


if __name__ == "__main__":
    main()
