"""Calibration by gradient against Bayesian optimisation (Optuna TPE), same problems.

    python experiments/diff/calibration.py [--trials 200] [--reference ../shared/sofa-reference]

1. Synthetic: a 60 mm beam (30 tetrahedra, two cables, tip load) pulled for 30 steps; every
   free node's trajectory generated with E = 200 kPa, nu = 0.3, alpha = 0.5, beta = 0.01, no
   noise. Both methods start from (300, 0.4, 1.0, 0.02) within the same bounds; L-BFGS-B
   (:func:`pliant.diff.calibration.calibrate`) runs to convergence, TPE for `--trials`
   rollouts (start enqueued, E, alpha, beta on log scales). Reported: loss (mm^2), relative
   parameter errors, rollouts and solver steps spent, wall time.
2. SOFA's Diamond under gravity (../shared/sofa-reference/diamond_plain.scn, 100 steps of
   0.01 s, SOFA's exported final positions): E alone from 30 % below and 30 % above the
   scene's 180 kPa, by both methods.

Writes experiments/results/diff/calibration.json. Timings are wall-clock on the shared 2-core
machine, under the load of other jobs.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
import optuna

from pliant.constraints.base import EmbeddedPoints
from pliant.diff import rollout, set_parameters
from pliant.diff.calibration import calibrate, observe, relative_errors, trajectory_loss
from pliant.diff.scenes import cable_beam as beam
from pliant.solvers import ImplicitEuler

ROOT = Path(__file__).resolve().parents[2]

OUT = ROOT / "experiments" / "results" / "diff" / "calibration.json"
DT = 0.01
TRUTH = dict(young_modulus=200.0, poisson_ratio=0.3, rayleigh_mass=0.5, rayleigh_stiffness=0.01)
START = dict(young_modulus=300.0, poisson_ratio=0.4, rayleigh_mass=1.0, rayleigh_stiffness=0.02)
BOUNDS = dict(
    young_modulus=(50.0, 1000.0),
    poisson_ratio=(0.05, 0.49),
    rayleigh_mass=(0.01, 5.0),
    rayleigh_stiffness=(0.001, 0.1),
)


def tpe(model, solver, state0, controls, points, observed, start, bounds, trials, stages):
    """Optuna TPE on the same loss: one rollout per trial."""
    loss = trajectory_loss(points, observed, stages)
    log_scale = {"young_modulus", "rayleigh_mass", "rayleigh_stiffness"}
    best, curve = [np.inf], []

    def objective(trial):
        values = {n: trial.suggest_float(n, *bounds[n], log=n in log_scale) for n in start}
        set_parameters(model, **values)
        states = rollout(model, solver, state0, controls)
        value = sum(
            loss.stage(n, s, None if n == 0 else controls[n - 1]).value
            for n, s in enumerate(states)
        )
        best[0] = min(best[0], value)
        curve.append(best[0])
        return value

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    study = optuna.create_study(sampler=optuna.samplers.TPESampler(seed=0))
    study.enqueue_trial(dict(start))
    t0 = time.perf_counter()
    study.optimize(objective, n_trials=trials)
    return study.best_params, study.best_value, curve, time.perf_counter() - t0


def synthetic(trials: int) -> dict:
    n_steps = 30
    controls = np.column_stack(
        [np.minimum(np.arange(1, n_steps + 1) * 0.5, 2.0), np.full(n_steps, 5.0)]
    )
    model = beam(**TRUTH)
    points = EmbeddedPoints.at_nodes(np.flatnonzero(model.body.free_index[::3] >= 0))
    observed = observe(
        model, ImplicitEuler(model, DT, tangent="fresh"), model.rest_state(), controls, points
    )
    fitted = beam(**START)
    solver = ImplicitEuler(fitted, DT, tangent="fresh")
    t0 = time.perf_counter()
    result = calibrate(
        fitted, solver, fitted.rest_state(), controls, points, observed, START, BOUNDS
    )
    wall = time.perf_counter() - t0
    gradient = {
        "parameters": result.parameters,
        "relative_errors": relative_errors(result.parameters, TRUTH),
        "loss_mm2": result.loss,
        "rollouts_with_adjoint": result.evaluations,
        "solver_steps": result.simulated_steps,
        "iterations": result.iterations,
        "wall_s": wall,
    }
    params, value, curve, wall = _tpe_beam(controls, points, observed, trials)
    bayes = {
        "parameters": params,
        "relative_errors": relative_errors(params, TRUTH),
        "loss_mm2": value,
        "rollouts": trials,
        "solver_steps": trials * n_steps,
        "best_loss_after": {
            str(k): curve[k - 1] for k in (10, 25, 50, 100, 200, 400) if k <= len(curve)
        },
        "wall_s": wall,
    }
    return {
        "scene": "beam, 30 tetrahedra, 2 cables, 30 steps, every free node observed",
        "truth": TRUTH,
        "start": START,
        "bounds": BOUNDS,
        "lbfgsb_adjoint": gradient,
        "optuna_tpe": bayes,
    }


def _tpe_beam(controls, points, observed, trials):
    model = beam(**START)
    solver = ImplicitEuler(model, DT, tangent="fresh")
    return tpe(
        model, solver, model.rest_state(), controls, points, observed, START, BOUNDS, trials, "all"
    )


def sofa_positions(path: Path) -> np.ndarray:
    words = path.read_text().split()
    at = words.index("POINTS")
    n = int(words[at + 1])
    return np.array(words[at + 3 : at + 3 + 3 * n], dtype=float).reshape(n, 3)


def sofa_diamond(reference: Path, meshes: Path, trials: int) -> dict:
    from pliant.sofa import load_scene

    loaded = load_scene(reference / "diamond_plain.scn", mesh_dirs=[meshes])
    model = loaded.model
    n_steps = 100
    controls = np.zeros((n_steps, 0))
    final = sofa_positions(reference / "diamond_plain_0.vtk")
    free = np.flatnonzero(model.body.free_index[::3] >= 0)
    points = EmbeddedPoints.at_nodes(free)
    observed = np.zeros((n_steps + 1, free.size, 3))
    observed[-1] = final[free]
    runs = {}
    for start in (126.0, 234.0):
        set_parameters(model, young_modulus=start)
        solver = ImplicitEuler(model, DT, tangent="fresh")
        bounds = {"young_modulus": (60.0, 600.0)}
        # the same problem for both methods: model, solver, start, actuation, data, box
        problem = (model, solver, model.rest_state(), controls, points, observed)
        start_box = ({"young_modulus": start}, bounds)
        t0 = time.perf_counter()
        result = calibrate(*problem, *start_box, stages="final", max_iterations=30)
        wall = time.perf_counter() - t0
        set_parameters(model, young_modulus=start)
        params, value, curve, tpe_wall = tpe(*problem, *start_box, trials, "final")
        runs[str(start)] = {
            "lbfgsb_adjoint": {
                "young_modulus": result.parameters["young_modulus"],
                "relative_error_to_scene": abs(result.parameters["young_modulus"] - 180.0) / 180.0,
                "rms_node_error_mm": float(np.sqrt(2.0 * result.loss)),
                "rollouts_with_adjoint": result.evaluations,
                "solver_steps": result.simulated_steps,
                "wall_s": wall,
            },
            "optuna_tpe": {
                "young_modulus": params["young_modulus"],
                "relative_error_to_scene": abs(params["young_modulus"] - 180.0) / 180.0,
                "rms_node_error_mm": float(np.sqrt(2.0 * value)),
                "rollouts": trials,
                "solver_steps": trials * n_steps,
                "wall_s": tpe_wall,
            },
        }
    return {
        "scene": "SOFA diamond_plain.scn (1628 nodes, 4147 tetrahedra, large frames),"
        " final positions after 100 steps",
        "scene_young_modulus": 180.0,
        "runs": runs,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=200)
    parser.add_argument("--sofa-trials", type=int, default=30)
    parser.add_argument("--reference", type=Path, default=ROOT.parent / "shared" / "sofa-reference")
    parser.add_argument("--meshes", type=Path, default=ROOT.parent / "shared" / "meshes")
    args = parser.parse_args()
    out = {"synthetic": synthetic(args.trials)}
    print(json.dumps(out, indent=1))
    if (args.reference / "diamond_plain_0.vtk").is_file():
        out["sofa_diamond"] = sofa_diamond(args.reference, args.meshes, args.sofa_trials)
    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.write_text(json.dumps(out, indent=1) + "\n")
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
