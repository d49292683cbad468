"""The Diamond reaching two successive goals by box-DDP on condensed FEM dynamics (thesis
§5.2.3, Fig. 5.20): the linear and the non-linear state derivative, numpy beside crocoddyl.

    python experiments/trajopt/diamond.py [--max-iterations 100]

Scenario (pliant.trajopt.scenarios.diamond_two_goals): Diamond mesh size 20 mm (2076 free
DoFs), dt = 0.02 s, N = 100 nodes (2 s), a goal per node (the first goal for the first half,
the second after), cable tensions 0..1500 mN changing by at most 40 mN per step from slack.
Runs:
  linear            Eq. 5.27's linear part (the thesis' choice), numpy backward pass
  linear-crocoddyl  the same with crocoddyl's Box-FDDP backward pass
  linear-augmented  the change bound as a box on the change (pliant.trajopt.rate)
  non-linear        with the non-linear part, the thesis' lift (pseudo-inverse of H_e)
  non-linear-compliance  with the non-linear part, the compliance lift
  non-linear-static with the non-linear part, the static (Guyan) lift
  linear-no-change-bound the linear run without the bound on the change per step
Then, on the condensed problem frozen along the linear run's solution (no change bound,
which crocoddyl's box does not take): one backward pass, numpy vs crocoddyl (median of 20),
and the whole solve of the frozen problem, numpy BoxDDP vs crocoddyl SolverBoxFDDP.
Writes experiments/results/trajopt/diamond.json and diamond.png.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

import numpy as np

from pliant.trajopt import ActuationBounds, BoxDDP, LinearDynamics
from pliant.trajopt.crocoddyl_backend import backward_pass as crocoddyl_backward
from pliant.trajopt.crocoddyl_backend import solve_frozen
from pliant.trajopt.ddp import backward_pass, compiled_backward_pass
from pliant.trajopt.plots import plot_trajectory
from pliant.trajopt.runs import summary
from pliant.trajopt.scenarios import diamond_two_goals

OUT = Path(__file__).parents[1] / "results" / "trajopt"
THESIS = {"linear_iterations": 208, "nonlinear_iterations": "1000 (the cap)"}


def median_time(fn, repeats: int = 20) -> float:
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return float(np.median(times))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--max-iterations", type=int, default=100)
    parser.add_argument("--tolerance", type=float, default=1e-4)
    parser.add_argument("--out", type=Path, default=OUT, help="folder of diamond.json and .png")
    args = parser.parse_args()
    runs = {
        "linear": ({}, "numpy", True),
        "linear-crocoddyl": ({}, "crocoddyl", True),
        "linear-augmented": ({}, "numpy", "augmented"),
        "non-linear": ({"nonlinear": True}, "numpy", True),
        "non-linear-compliance": ({"nonlinear": True, "lift": "compliance"}, "numpy", True),
        "non-linear-static": ({"nonlinear": True, "lift": "static"}, "numpy", True),
        "linear-no-change-bound": ({}, "numpy", False),
    }
    reports, plotted, solutions = [], {}, {}
    for name, (options, backend, change_bound) in runs.items():
        scenario = diamond_two_goals(**options)
        bounds = scenario.bounds
        if not change_bound:
            bounds = ActuationBounds(bounds.lower, bounds.upper)
        solver = BoxDDP(
            max_iterations=args.max_iterations,
            tolerance=args.tolerance,
            backend=backend,
            change_bound="augmented" if change_bound == "augmented" else "sequential",
        )
        result = solver.solve(scenario.dynamics, scenario.start, scenario.cost, bounds)
        report = summary(name, result, scenario)
        reports.append(report)
        solutions[name] = (scenario, result)
        print(
            f"{name}: {result.iterations} iterations ({result.reason}), cost {result.cost:.1f},"
            f" {result.wall_time:.1f} s ({result.rollouts} rollouts,"
            f" backward {result.backward_time:.2f} s), end error"
            f" {report['error_final_goal_at_end']:.3f} mm",
            flush=True,
        )
        if name in ("linear", "non-linear"):
            plotted[name] = (result.xs, result.us)

    # numpy vs crocoddyl on the condensed problem frozen along the linear solution.
    scenario, result = solutions["linear"]
    fx, fu = scenario.dynamics.derivatives(result.rollout)
    xs, us = result.xs, result.us
    box = (scenario.bounds.lower, scenario.bounds.upper)
    boxes = [box] * us.shape[0]
    frozen = LinearDynamics.along(xs, us, fx, fu)
    plain = ActuationBounds(*box)
    ours = BoxDDP(tolerance=1e-10, max_iterations=200)
    numpy_solve = ours.solve(frozen, xs[0], scenario.cost, plain, us)
    t = time.perf_counter()
    cxs, cus, c_iter, c_wall = solve_frozen(
        xs[0], fx, fu, frozen.c, scenario.cost, plain, us, max_iterations=200, tolerance=1e-10
    )
    comparison = {
        "backward_pass_numpy_reference_s": median_time(
            lambda: backward_pass(xs, us, fx, fu, scenario.cost, boxes)
        ),
        "backward_pass_compiled_s": median_time(
            lambda: compiled_backward_pass(xs, us, fx, fu, scenario.cost, boxes)
        ),
        "backward_pass_crocoddyl_s": median_time(
            lambda: crocoddyl_backward(xs, us, fx, fu, scenario.cost, boxes)
        ),
        "frozen_solve_numpy": {
            "iterations": numpy_solve.iterations,
            "wall_time_s": numpy_solve.wall_time,
            "cost": numpy_solve.cost,
        },
        "frozen_solve_crocoddyl": {
            "iterations": int(c_iter),
            "wall_time_s": c_wall,
            "wall_time_with_setup_s": time.perf_counter() - t,
            "cost": scenario.cost.value(cxs, cus),
        },
        "frozen_solve_max_control_difference_mN": float(np.abs(numpy_solve.us - cus).max()),
        "fem_rollout_s": result.forward_time / result.rollouts,
    }
    print(json.dumps(comparison, indent=1))
    args.out.mkdir(parents=True, exist_ok=True)
    times = np.arange(scenario.cost.horizon + 1) * scenario.dynamics.dt
    plot_trajectory(
        times,
        plotted,
        scenario.goals,
        box,
        args.out / "diamond.png",
        title="Diamond, two successive goals: box-DDP, full-FEM forward pass",
    )
    (args.out / "diamond.json").write_text(
        json.dumps(
            {
                "command": "python experiments/trajopt/diamond.py",
                "scenario": {
                    "mesh_size_mm": 20.0,
                    "free_dofs": int(scenario.model.body.n_free),
                    "dt_s": scenario.dynamics.dt,
                    "horizon": scenario.cost.horizon,
                    "goals_mm": [g.tolist() for g in np.unique(scenario.goals, axis=0)],
                    "bounds_mN": [0.0, 1500.0],
                    "max_change_mN_per_step": 40.0,
                    "tolerance": args.tolerance,
                },
                "thesis": THESIS,
                "load_average_1min_at_end": os.getloadavg()[0],
                "cores": os.cpu_count(),
                "runs": reports,
                "numpy_vs_crocoddyl": comparison,
            },
            indent=1,
        )
    )
    print(f"wrote {args.out / 'diamond.json'} and {args.out / 'diamond.png'}")


if __name__ == "__main__":
    main()
