"""Control by gradient against box-DDP: the Diamond's two-goal task and the Trunk reaching a
goal, same problem, same run.

    python experiments/diff/control.py [--task diamond|trunk] [--quick] [--fresh]

The problem is `pliant trajopt diamond`'s (pliant.trajopt.scenarios.diamond_two_goals):
Diamond mesh size 20 mm, dt = 0.02 s, N = 100 steps, the effector to the first goal for the
first half and the second after, from the static equilibrium under gravity, cost

    J = sum_{k=0}^{N} 1/2 (|p_k - g_k|^2 + 1e-3 |p_dot_k|^2) + sum_{k<N} 1/2 1e-6 |u_k|^2,

cable tensions 0 <= u <= 1500 mN. In pliant.diff terms: PointTracking of the effector point
(weight 1, every stage), PointTracking of its velocity (quantity "velocities", weight 1e-3,
zero targets) and ControlPenalty(1e-6), on the Diamond with its cables in force mode (the
DDP's ForceControl applies the same forces). What a box cannot hold: the DDP's bound on the
change per step |u_k - u_{k-1}| <= 40 mN. L-BFGS-B solves the problem without it; the DDP is
run both with it (the `pliant trajopt diamond` default) and without it (the same problem as
L-BFGS-B's), and the L-BFGS-B solution's largest change per step is reported.

Runs, in this order in one process (wall times side by side, on the shared 2-core machine
under other jobs' load): box-DDP with the change bound, box-DDP without it (numpy backward
pass, linear state derivative, tolerance 1e-4 on the cost decrease, at most 100 iterations),
L-BFGS-B from zero controls (pliant.diff.optimise_controls, at most 100 iterations too).
Both are warmed up first (numba compilation, untimed). Every final cost is evaluated again
on the same full-FEM rollout (pliant.diff's loss).

The Trunk (`--task trunk`, pliant.trajopt.scenarios.trunk_reach): the default mesh (2056
tetrahedra, 1557 free DoFs), dt = 0.02 s, N = 50 steps, its tip to one goal (where tensions
(1000, 0, 0, 600, 0, 0, 0, 0) mN hold it after 2 s, about 30 mm from where it hangs), the same
cost weights, tensions 0 <= u <= 1500 mN, the DDP's change bound 100 mN per step; the same
three runs; the coarse Trunk (mesh size 8 mm, 712 tetrahedra) with --quick.

Writes experiments/results/diff/control.json (the Diamond) or control_trunk.json after each run
(atomically); a run already in the file is kept unless --fresh. --quick: N = 10, 5 iterations
each, to out/diff/.
"""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path

import numpy as np

from pliant import robots
from pliant.diff import (
    ControlPenalty,
    Losses,
    PointTracking,
    optimise_controls,
    rollout,
    rollout_gradient,
)
from pliant.files import write_results
from pliant.solvers import ImplicitEuler
from pliant.trajopt import ActuationBounds, BoxDDP
from pliant.trajopt.scenarios import diamond_two_goals, trunk_reach

ROOT = Path(__file__).resolve().parents[2]
RESULTS = ROOT / "experiments" / "results" / "diff"
OUT = {"diamond": RESULTS / "control.json", "trunk": RESULTS / "control_trunk.json"}


def task(name: str, quick: bool):
    """The scenario (for the DDP), the same robot with force-mode cables (for pliant.diff)
    and a description of the problem."""
    horizon = 10 if quick else {"diamond": 100, "trunk": 50}[name]
    if name == "diamond":
        scenario = diamond_two_goals(horizon=horizon)
        model = robots.diamond(mesh_size=20.0, cable_mode="force")
        described = {
            "scenario": "pliant.trajopt.scenarios.diamond_two_goals (pliant trajopt diamond)",
            "mesh_size_mm": 20.0,
        }
    else:
        mesh_size = 8.0 if quick else 5.2
        scenario = trunk_reach(horizon=horizon, mesh_size=mesh_size)
        model = robots.trunk(mesh_size=mesh_size, cable_mode="force")
        described = {
            "scenario": "pliant.trajopt.scenarios.trunk_reach (one goal)",
            "mesh_size_mm": mesh_size,
            "elements": int(model.body.n_elements),
        }
    return scenario, model, described


def diff_problem(scenario, horizon: int, model):
    """`model` (the scenario's robot with force-mode cables), its exact solver and the trajopt
    cost as pliant.diff stage losses."""
    cost = scenario.cost
    (effector,) = model.effectors
    if len(effector.points) != 1 or effector.axes.tolist() != [0, 1, 2]:
        raise SystemExit("the translation assumes one effector point on x, y, z")
    m = 3
    weights = cost.state_weights
    # tracking_cost's weights are uniform here: read them back rather than restate them.
    position_weight, velocity_weight = float(weights[0, 0]), float(weights[0, m])
    if not (
        np.all(weights[:, :m] == position_weight) and np.all(weights[:, m:] == velocity_weight)
    ):
        raise SystemExit("the translation assumes uniform weights over the stages")
    control_weight = float(cost.control_weights[0])
    if not np.all(cost.control_weights == control_weight) or np.any(cost.control_reference):
        raise SystemExit("the translation assumes one control weight and u_ref = 0")
    goals = cost.state_reference[:, None, :m]
    loss = Losses(
        PointTracking(effector.points, goals, n_steps=horizon, weight=position_weight),
        PointTracking(
            effector.points,
            np.zeros((1, 3)),
            n_steps=horizon,
            weight=velocity_weight,
            quantity="velocities",
        ),
        ControlPenalty(control_weight),
    )
    weights_used = {"position": position_weight, "velocity": velocity_weight}
    weights_used["control"] = control_weight
    return model, ImplicitEuler(model, scenario.dynamics.dt, tangent="fresh"), loss, weights_used


def full_fem_cost(model, solver, start, controls, loss) -> float:
    """The loss of the controls' full-FEM rollout (the same for every method)."""
    states = rollout(model, solver, start, controls)
    total = 0.0
    for n, state in enumerate(states):
        total += loss.stage(n, state, None if n == 0 else controls[n - 1]).value
    return total


def max_change(controls: np.ndarray) -> float:
    """The largest change of a tension from one step to the next (from 0 before the first)."""
    return float(np.abs(np.diff(np.vstack([np.zeros(controls.shape[1]), controls]), axis=0)).max())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--task", choices=("diamond", "trunk"), default="diamond")
    parser.add_argument("--quick", action="store_true", help="N = 10, 5 iterations each")
    parser.add_argument("--fresh", action="store_true", help="rerun runs already in the file")
    parser.add_argument("--ddp-iterations", type=int, default=100)
    parser.add_argument("--lbfgs-iterations", type=int, default=100)
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    ddp_iterations = 5 if args.quick else args.ddp_iterations
    lbfgs_iterations = 5 if args.quick else args.lbfgs_iterations
    quick_out = ROOT / "out" / "diff" / f"{OUT[args.task].stem}_quick.json"
    out = args.out or (quick_out if args.quick else OUT[args.task])
    data = json.loads(out.read_text()) if out.exists() and not args.fresh else {}
    runs = data.setdefault("runs", {})

    scenario, model, described = task(args.task, args.quick)
    horizon = scenario.goals.shape[0] - 1
    model, solver, loss, weights = diff_problem(scenario, horizon, model)
    bounds = scenario.bounds
    data["command"] = f"python experiments/diff/control.py --task {args.task}" + (
        " --quick" if args.quick else ""
    )
    data["problem"] = {
        **described,
        "free_dofs": int(model.body.n_free),
        "dt_s": scenario.dynamics.dt,
        "horizon": horizon,
        "goals_mm": [g.tolist() for g in np.unique(scenario.goals, axis=0)],
        "weights": weights,
        "tension_bounds_mN": [float(bounds.lower[0]), float(bounds.upper[0])],
        "ddp_max_change_mN_per_step": float(bounds.max_change[0]),
        "not_expressible_as_a_box": "the DDP's |u_k - u_(k-1)| <= max_change: L-BFGS-B runs"
        " without it; compare with box-DDP without it (same problem) and with it",
    }

    def save() -> None:
        data["load_average_1min_at_save"] = os.getloadavg()[0]
        data["cores"] = os.cpu_count()
        write_results(out, data)

    # Warm-up, untimed: the compiled kernels of both methods (numba) on this problem.
    BoxDDP(max_iterations=1).solve(scenario.dynamics, scenario.start, scenario.cost, bounds)
    warm = np.zeros((2, model.n_actuators))
    rollout_gradient(model, solver, scenario.start, warm, loss, wrt=("controls",))

    ddp_runs = {
        "box-DDP, change bound"
        + (" (pliant trajopt diamond)" if args.task == "diamond" else ""): bounds,
        "box-DDP, no change bound": ActuationBounds(bounds.lower, bounds.upper),
    }
    for name, run_bounds in ddp_runs.items():
        if name in runs:
            continue
        ddp = BoxDDP(max_iterations=ddp_iterations, tolerance=1e-4)
        result = ddp.solve(scenario.dynamics, scenario.start, scenario.cost, run_bounds)
        controls = np.asarray(result.us)
        runs[name] = {
            "iterations": result.iterations,
            "converged": bool(result.converged),
            "reason": result.reason,
            "full_fem_rollouts": result.rollouts,
            "wall_time_s": result.wall_time,
            "cost_reported_by_ddp": result.cost,
            "cost_full_fem": full_fem_cost(model, solver, scenario.start, controls, loss),
            "max_change_mN_per_step": max_change(controls),
            "controls_mN": controls.tolist(),
        }
        print(name, {k: v for k, v in runs[name].items() if k != "controls_mN"}, flush=True)
        save()

    name = "L-BFGS-B + adjoint, no change bound"
    if name not in runs:
        result = optimise_controls(
            model,
            solver,
            scenario.start,
            loss,
            np.zeros((horizon, model.n_actuators)),
            lower=bounds.lower,
            upper=bounds.upper,
            max_iterations=lbfgs_iterations,
            callback=lambda i, e, v, t: print(
                f"L-BFGS-B {i}: {e} evaluations, {t:.0f} s, loss {v:.2f}"
            ),
        )
        below = {}
        for other, report in runs.items():
            hit = next(
                (it for it in result.iteration_losses if it[2] <= report["cost_full_fem"]), None
            )
            below[other] = (
                None
                if hit is None
                else {"iteration": hit[0], "evaluations": hit[1], "wall_time_s": hit[3]}
            )
        runs[name] = {
            "iterations": result.iterations,
            "converged": result.converged,
            "reason": result.message,
            "full_fem_rollouts": result.evaluations,
            "adjoint_sweeps": result.evaluations,
            "solver_steps": result.simulated_steps,
            "wall_time_s": result.wall_time,
            "cost_lbfgs": result.loss,
            "cost_full_fem": full_fem_cost(model, solver, scenario.start, result.controls, loss),
            "max_change_mN_per_step": max_change(result.controls),
            "first_below": below,
            "iteration_losses": result.iteration_losses,
            "controls_mN": result.controls.tolist(),
        }
        print(
            name,
            {
                k: runs[name][k]
                for k in (
                    "iterations",
                    "full_fem_rollouts",
                    "wall_time_s",
                    "cost_full_fem",
                    "first_below",
                )
            },
            flush=True,
        )
        save()
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
