"""What a rollout gradient costs beside the rollout it differentiates (`pliant bench
--gradient`, experiments/diff/cost.py).

A T-step rollout of the robot under a ramped actuation is timed ("fresh" tangent, as the
adjoint needs), then :func:`pliant.diff.rollout_gradient` of a point-tracking loss with respect
to the actuation, Young's modulus and Poisson's ratio, keeping every state and with checkpoints
every ceil(sqrt(T)) steps. The ratio of the two wall times is the figure issue 63 bounds by 3;
measured in one process one after the other, it holds on a shared machine better than either
time alone. With `repeats` > 1 the three are timed in turn, interleaved, that many times, and
each figure is the median (the ratios are medians of each repeat's own ratio).
"""

from __future__ import annotations

import time
import tracemalloc

import numpy as np

from pliant.diff.losses import PointTracking
from pliant.diff.rollout import rollout, rollout_gradient
from pliant.errors import ModelError
from pliant.model import Model
from pliant.solvers import ImplicitEuler

WRT = ("controls", "young_modulus", "poisson_ratio")


def gradient_cost(
    model: Model,
    commands: np.ndarray,
    n_steps: int,
    *,
    dt: float = 0.01,
    memory: bool = False,
    repeats: int = 1,
) -> dict:
    """Time the forward rollout and its gradient (module docstring), `repeats` times
    interleaved, medians. The actuation ramps to `commands` over the first 30 % of the steps;
    the loss tracks the first effector's points towards their rest positions + 1 mm. With
    `memory`, each gradient runs again under tracemalloc for the peak of Python-allocated
    memory (not timed)."""
    commands = np.asarray(commands, dtype=float)
    if n_steps < 2 or commands.shape != (len(model.actuators),) or not model.effectors:
        raise ModelError(
            "gradient_cost needs >= 2 steps, one command per actuator and an effector; got"
            f" {n_steps} steps, commands of shape {commands.shape} for"
            f" {len(model.actuators)} actuators, {len(model.effectors)} effectors"
        )
    if int(repeats) != repeats or repeats < 1:
        raise ModelError(f"gradient_cost needs repeats >= 1, got {repeats}")
    ramp = np.minimum(np.arange(1, n_steps + 1) / (0.3 * n_steps), 1.0)[:, None]
    controls = ramp * commands[None, :]
    points = model.effectors[0].points
    goal = points.positions(model.body.rest_positions) + 1.0
    loss = PointTracking(points, goal, n_steps=n_steps)
    solver = ImplicitEuler(model, dt, tangent="fresh")
    rollout_gradient(model, solver, model.rest_state(), controls[:2], loss, wrt=WRT)  # compile
    every_sqrt = int(np.ceil(np.sqrt(n_steps)))
    cases = (("all_states_kept", None), ("checkpoints_sqrt_T", every_sqrt))
    forwards, walls, results = [], {label: [] for label, _ in cases}, {}
    for _ in range(int(repeats)):
        t0 = time.perf_counter()
        rollout(model, solver, model.rest_state(), controls)
        forwards.append(time.perf_counter() - t0)
        for label, every in cases:
            t0 = time.perf_counter()
            results[label] = rollout_gradient(
                model, solver, model.rest_state(), controls, loss, wrt=WRT, checkpoint_every=every
            )
            walls[label].append(time.perf_counter() - t0)
    row = {
        "nodes": model.body.n_nodes,
        "elements": model.body.n_elements,
        "steps": n_steps,
        "repeats": int(repeats),
        "forward_s": float(np.median(forwards)),
        "state_MB": 2 * model.rest_state().positions.nbytes / 2**20,
    }
    if repeats > 1:
        row["forward_s_each"] = forwards
    for label, every in cases:
        ratios = np.asarray(walls[label]) / np.asarray(forwards)
        row[label] = {
            "gradient_s": float(np.median(walls[label])),
            "gradient_over_forward": float(np.median(ratios)),
            "solver_steps": results[label].forward_steps,
            "states_held": results[label].states_held,
        }
        if repeats > 1:
            row[label]["gradient_s_each"] = walls[label]
            row[label]["ratio_each"] = ratios.tolist()
        if memory:
            tracemalloc.start()
            rollout_gradient(
                model, solver, model.rest_state(), controls, loss, wrt=WRT, checkpoint_every=every
            )
            row[label]["peak_traced_MB"] = tracemalloc.get_traced_memory()[1] / 2**20
            tracemalloc.stop()
    return row
