"""A probe of the condensed-dynamics DDP on a stiff rod lattice: a Lianford-like parallel
robot (not a Pliant robot builder yet).

    python experiments/trajopt/lianford_probe.py

Six rod legs (circular section r = 2 mm, E = 20 MPa, nu = 0.4, 6 elements each) from base
points on a 60 mm circle up to a 15 mm ring at 70 mm, welded by spokes to a central handle
node (the effector); each leg's base is pinned (a ball joint) and turned by a motor torque
about the horizontal tangent (RotationActuator in force mode, |u| <= 5e4 mN mm, at most 5e3 per
step). Two tasks over N = 100 steps of 0.02 s: a spiral (a goal every step, radius growing to
5 mm over two turns, rising 5 mm), and a reference made feasible by construction (the handle's
path under known sinusoidal torques of 8000 mN mm, so that zero error is reachable). For the
linear part of Eq. 5.27 and the static lift: iterations, rollouts, RMS and largest distance to
the goals. Writes experiments/results/trajopt/lianford_probe.json.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from pliant.constraints.base import EmbeddedPoints
from pliant.constraints.effector import PositionEffector
from pliant.constraints.joint import RotationActuator
from pliant.fem.material import Corotational
from pliant.fem.rod import RodBody, RodSection
from pliant.model import Model
from pliant.solvers import StaticSolver
from pliant.trajopt import ActuationBounds, BoxDDP, CondensedDynamics, ForceControl, tracking_cost

OUT = Path(__file__).parents[1] / "results" / "trajopt"
DT, N = 0.02, 100


def lianford_like(elements: int = 6, legs: int = 6) -> Model:
    points, pairs, bases, axes = [[0.0, 0.0, 70.0]], [], [], []
    for i in range(legs):
        a = 2.0 * np.pi * i / legs
        base = np.array([60.0 * np.cos(a), 60.0 * np.sin(a), 0.0])
        top = np.array([15.0 * np.cos(a), 15.0 * np.sin(a), 70.0])
        first = len(points)
        points += [list((1.0 - s) * base + s * top) for s in np.linspace(0.0, 1.0, elements + 1)]
        pairs += [[first + j, first + j + 1] for j in range(elements)] + [[first + elements, 0]]
        bases.append(first)
        axes.append([-np.sin(a), np.cos(a), 0.0])
    body = RodBody(
        np.array(points),
        RodSection.circle(2.0),
        Corotational(2e4, 0.4),
        density=1.2e-6,
        elements=np.array(pairs),
        pinned=bases,
        gravity=(0.0, 0.0, -9810.0),
        rayleigh_mass=2.0,
    )
    motors = [
        RotationActuator(body, b, ax, mode="force", name=f"motor_{i}")
        for i, (b, ax) in enumerate(zip(bases, axes, strict=True))
    ]
    handle = PositionEffector(EmbeddedPoints.at_nodes([0]), body.rest_positions, name="handle")
    return Model(body, actuators=motors, effectors=[handle], name="lianford_like")


def main() -> None:
    model = lianford_like()
    start = StaticSolver(model).step(model.rest_state(), ForceControl(np.zeros(6)))
    t = np.arange(N + 1) * DT
    duration = N * DT
    bounds = ActuationBounds(
        np.full(6, -5e4), np.full(6, 5e4), max_change=np.full(6, 5e3), previous=np.zeros(6)
    )
    linear = CondensedDynamics(model, DT)
    x0 = linear.effector_state(start)[:3]
    radius, angle = 5.0 * t / duration, 4.0 * np.pi * t / duration
    spiral = x0 + np.column_stack(
        [radius * np.cos(angle), radius * np.sin(angle), 5.0 * t / duration]
    )
    phase = 2.0 * np.pi * np.arange(6) / 6
    torques = np.array(
        [8000.0 * np.sin(4.0 * np.pi * s / duration - phase) * min(1.0, s / 0.5) for s in t[:-1]]
    )
    feasible = linear.rollout(start, torques).xs[:, :3]
    runs = []
    for task, goals in (("spiral", spiral), ("feasible", feasible)):
        cost = tracking_cost(goals, n_controls=6, velocity_weight=1e-4, control_weight=1e-9)
        static = {"nonlinear": True, "lift": "static"}
        for name, options in (("linear", {}), ("static lift", static)):
            dyn = CondensedDynamics(model, DT, **options)
            result = BoxDDP(max_iterations=100, tolerance=1e-4).solve(dyn, start, cost, bounds)
            errors = np.linalg.norm(result.xs[:, :3] - goals, axis=1)
            run = {
                "task": task,
                "state_derivative": name,
                "iterations": result.iterations,
                "rollouts": result.rollouts,
                "reason": result.reason,
                "wall_time_s": result.wall_time,
                "cost": result.cost,
                "rms_error_mm": float(np.sqrt(np.mean(errors**2))),
                "max_error_mm": float(errors.max()),
                "goal_amplitude_mm": float(np.abs(goals - x0).max()),
                "bound_violation": result.bound_violation,
            }
            runs.append(run)
            print(run, flush=True)
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / "lianford_probe.json").write_text(
        json.dumps(
            {
                "command": "python experiments/trajopt/lianford_probe.py",
                "free_dofs": int(model.body.n_free),
                "runs": runs,
            },
            indent=1,
        )
    )


if __name__ == "__main__":
    main()
