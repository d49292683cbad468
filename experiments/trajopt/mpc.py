"""Receding-horizon MPC on the Diamond's two-goal task, the loop closed on the full FEM,
against the full-FEM box-DDP (pliant.trajopt.mpc; thesis §6.2.1 perspective).

    python experiments/trajopt/mpc.py

Same task as experiments/trajopt/diamond.py (mesh size 20 mm, dt = 0.02 s, 100 steps, cable
tensions 0..1500 mN, at most 40 mN per step). The prediction is the condensed dynamics frozen
at each FEM state (exact W_ea of the last step, free motion held over the horizon). For
horizons 10, 20, 40 and 1, 3, 10 DDP iterations per step (warm-started): the controller's
loop rate (median solve time), the closed-loop rate with the FEM step, the task cost, the
RMS distance to the goals and to the full-FEM DDP's effector trajectory. Writes
experiments/results/trajopt/mpc.json and mpc.png.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

from pliant.trajopt import BoxDDP
from pliant.trajopt.mpc import CondensedMPC
from pliant.trajopt.plots import plot_trajectory
from pliant.trajopt.scenarios import diamond_two_goals

OUT = Path(__file__).parents[1] / "results" / "trajopt"


def rms(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.sum((a - b) ** 2, axis=1))))


def main() -> None:
    scenario = diamond_two_goals()
    ddp = BoxDDP(max_iterations=100, tolerance=1e-4).solve(
        scenario.dynamics, scenario.start, scenario.cost, scenario.bounds
    )
    goals = scenario.goals
    reference = {
        "iterations": ddp.iterations,
        "wall_time_s": ddp.wall_time,
        "cost": ddp.cost,
        "rms_to_goals_mm": rms(ddp.xs[:, :3], goals),
    }
    print("full-FEM DDP:", reference, flush=True)
    runs, plotted = [], {"full-FEM DDP": (ddp.xs, ddp.us)}
    for horizon in (10, 20, 40):
        for iterations in (1, 3, 10):
            scenario = diamond_two_goals()
            mpc = CondensedMPC(
                scenario.dynamics,
                scenario.cost,
                scenario.bounds,
                horizon=horizon,
                max_iterations=iterations,
            )
            result = mpc.run(scenario.start)
            run = {
                "horizon": horizon,
                "iterations_per_step": iterations,
                **result.report(),
                "cost": scenario.cost.value(result.xs, result.us),
                "rms_to_goals_mm": rms(result.xs[:, :3], goals),
                "rms_to_ddp_mm": rms(result.xs[:, :3], ddp.xs[:, :3]),
                "end_error_mm": float(np.linalg.norm(result.xs[-1, :3] - goals[-1])),
                "bound_violation": scenario.bounds.violation(result.us),
            }
            runs.append(run)
            print(run, flush=True)
            if horizon == 20 and iterations == 3:
                plotted["MPC, horizon 20, 3 iterations"] = (result.xs, result.us)
    OUT.mkdir(parents=True, exist_ok=True)
    times = np.arange(goals.shape[0]) * scenario.dynamics.dt
    plot_trajectory(
        times,
        plotted,
        goals,
        (scenario.bounds.lower, scenario.bounds.upper),
        OUT / "mpc.png",
        title="Diamond, two goals: full-FEM DDP beside MPC closed on the FEM",
    )
    (OUT / "mpc.json").write_text(
        json.dumps(
            {
                "command": "python experiments/trajopt/mpc.py",
                "load_average_1min_at_end": os.getloadavg()[0],
                "cores": os.cpu_count(),
                "ddp": reference,
                "mpc": runs,
            },
            indent=1,
        )
    )
    print(f"wrote {OUT / 'mpc.json'} and {OUT / 'mpc.png'}")


if __name__ == "__main__":
    main()
