"""Reduced vs full Multigait over the hand gait and a held-out action sequence (issue 17).

    OPENBLAS_NUM_THREADS=1 nice python experiments/reduction/multigait.py [--mesh-size 6]
        [--reference /work/shared/meshes] [--pod 1e-3,3e-4,1e-4] [--tau 0.03,0.01,0.003]

Training: the full FEM (ImplicitEuler, dt 0.01 s) runs the Multigait's load cases
(pliant.reduction.multigait_cases: one hand-gait cycle, each symmetric group alone, three
random sequences of six discrete environment actions), positions every 5 steps, into
`cache/` (HDF5, resumable, not committed; the full runs of the tests are kept there too).
Evaluation: the hand gait (`--cycles` cycles: the first is in the training set) and a
held-out sequence of six actions (another seed), full FEM against each reduced model of the
grid of POD tolerances x ECSW tolerances (the same tau for the tetrahedra and the membrane;
and with every element, tau = 0): node-position error (max and
RMS over nodes and recorded steps, mm and % of the body length), centre-of-mass travel along
x and its error, steps/s of both (median of chunks of 60 steps, wall clock; the machine is a
2-core one shared with other jobs, so timings are noisy and low: the steps per second of the
process' CPU time are reported beside them).
Writes experiments/results/reduction/multigait_<mesh>.json and .png.
"""

from __future__ import annotations

import argparse
import json
import os
import time
import warnings
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from pliant.bench import multigait_reference  # noqa: E402
from pliant.errors import ContactConvergenceWarning, DivergenceError  # noqa: E402
from pliant.reduction import snapshots  # noqa: E402
from pliant.reduction.pipeline import build, multigait_cases  # noqa: E402
from pliant.reduction.solver import ReducedImplicitEuler  # noqa: E402
from pliant.robots.multigait import centre_of_mass, demo_actuation, multigait  # noqa: E402
from pliant.solvers import ImplicitEuler  # noqa: E402
from pliant.viz import save_figure

DT, EVERY, CHUNK = 0.01, 5, 60


def run(solver, state, commands, steps: int) -> dict:
    """Positions every EVERY steps, the median steps/s of chunks of CHUNK steps (wall clock),
    and the steps per second of this process' CPU time (all its threads)."""
    recorded, rates = [], []
    clock, cpu = time.perf_counter(), time.process_time()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ContactConvergenceWarning)
        for k in range(1, steps + 1):
            state = solver.step(state, commands(state.time))
            if k % EVERY == 0:
                recorded.append(np.array(state.positions))
            if k % CHUNK == 0:
                now = time.perf_counter()
                rates.append(CHUNK / (now - clock))
                clock = time.perf_counter()
    return {
        "positions": np.array(recorded),
        "steps_per_s": float(np.median(rates)),
        "steps_per_cpu_s": steps / (time.process_time() - cpu),
    }


def compare(model, full: dict, reduced: dict) -> dict:
    length = float(np.ptp(model.body.rest_positions[:, 0]))
    error = np.linalg.norm(reduced["positions"] - full["positions"], axis=2)
    x0 = centre_of_mass(model, model.body.rest_positions)[0]
    travel_full = float(centre_of_mass(model, full["positions"][-1])[0] - x0)
    travel = float(centre_of_mass(model, reduced["positions"][-1])[0] - x0)
    return {
        "max_error_mm": float(error.max()),
        "rms_error_mm": float(np.sqrt(np.mean(error**2))),
        "max_error_pct_length": float(100 * error.max() / length),
        "rms_error_pct_length": float(100 * np.sqrt(np.mean(error**2)) / length),
        "travel_full_mm": travel_full,
        "travel_reduced_mm": travel,
        "travel_error_pct": float(100 * abs(travel - travel_full) / abs(travel_full)),
        "steps_per_s": reduced["steps_per_s"],
        "steps_per_cpu_s": reduced["steps_per_cpu_s"],
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--mesh-size", type=float, default=6.0)
    parser.add_argument("--reference", type=Path, default=None, help="SOFA meshes folder")
    parser.add_argument("--pod", default="1e-3,1e-4,1e-5")
    parser.add_argument("--tau", default="0.01,0.003,0.001")
    parser.add_argument("--cycles", type=int, default=1)
    parser.add_argument("--sequences", type=int, default=3, help="random training sequences")
    parser.add_argument(
        "--amplitude", default="4900,3300", help="centre and leg volume growth (mm^3)"
    )
    parser.add_argument("--all-elements", action="store_true", help="also tau = 0")
    parser.add_argument(
        "--reuse-gait",
        action="store_true",
        help="the full gait is the training case's (recorded every 5 steps, as here), timed"
        " over 60 steps only (for a slow full model; needs --cycles 1)",
    )
    parser.add_argument("--no-held-out", action="store_true", help="only the gait")
    parser.add_argument("--out", type=Path, default=Path("experiments/results/reduction"))
    args = parser.parse_args()
    if args.reference is not None:
        model, label = multigait_reference(args.reference), "reference"
    else:
        model, label = multigait(mesh_size=args.mesh_size), f"mesh{args.mesh_size:g}"
    cache = args.out / "cache" / label
    began = time.perf_counter()
    amplitude = tuple(float(a) for a in args.amplitude.split(","))
    cases = multigait_cases(amplitude=amplitude, sequences=args.sequences)
    path = snapshots.collect(model, cases, cache / "snapshots.h5", dt=DT)
    collect_s = time.perf_counter() - began
    positions = np.concatenate([p for _, p in snapshots.load(path, model).values()])
    held_out = multigait_cases(amplitude=amplitude, sequences=1, seed=1)[-1]
    tests = {
        "gait": (
            lambda t: demo_actuation(t, amplitude=amplitude),
            round(6 * 0.6 * args.cycles / DT),
        ),
        "held_out": (held_out.commands, round(held_out.duration / DT)),
    }
    if args.no_held_out:
        del tests["held_out"]
    full = {}
    for name, (commands, steps) in tests.items():
        saved = cache / f"full_{name}_{steps}.npz"
        if saved.exists():  # the full runs are the slow part: kept beside the snapshots
            with np.load(saved) as data:
                full[name] = {
                    "positions": data["positions"],
                    "steps_per_s": float(data["steps_per_s"]),
                    "steps_per_cpu_s": float(data["steps_per_cpu_s"]),
                }
            continue
        if name == "gait" and args.reuse_gait:
            timed = run(ImplicitEuler(model, DT), model.rest_state(), commands, CHUNK)
            recorded = snapshots.load(path, model, ["gait"])["gait"][1]
            full[name] = {**timed, "positions": recorded[: steps // EVERY]}
        else:
            full[name] = run(ImplicitEuler(model, DT), model.rest_state(), commands, steps)
        np.savez(saved, **full[name])
        print(
            f"full {name}: {full[name]['steps_per_s']:.1f} steps/s,"
            f" {full[name]['steps_per_cpu_s']:.1f} per CPU second",
            flush=True,
        )
    results = {
        "model": label,
        "amplitude_mm3": list(amplitude),
        "tetrahedra": model.body.n_elements,
        "nodes": model.body.n_nodes,
        "membrane_triangles": [len(a.membrane.triangles) for a in model.body.membranes],
        "contact_points": len(model.contacts.points),
        "snapshots": len(positions),
        "collect_seconds": collect_s,
        "full_steps_per_s": {k: v["steps_per_s"] for k, v in full.items()},
        "full_steps_per_cpu_s": {k: v["steps_per_cpu_s"] for k, v in full.items()},
        "blas_threads": os.environ.get("OPENBLAS_NUM_THREADS", "default"),
        "reduced": [],
    }
    taus = [float(t) for t in args.tau.split(",")] + ([0.0] if args.all_elements else [])
    for pod_tol in (float(p) for p in args.pod.split(",")):
        for tau in taus:
            reduced = build(
                model, positions, pod_tolerance=pod_tol, tau=tau or 0.5, tau_membrane=tau or 0.5
            )
            meta = reduced.metadata
            entry = {
                "pod_tolerance": pod_tol,
                "tau": tau,
                "modes": meta["n_modes"],
                "tets_selected": meta["tets_selected"] if tau else model.body.n_elements,
                "triangles_selected": meta["triangles_selected"]
                if tau
                else meta["triangles_total"],
                "ecsw_error_tets": meta["ecsw_error_tets"] if tau else 0.0,
                "projection_error_max_mm": meta["projection_error_max_mm"],
                "build_seconds": meta["build_seconds"],
            }
            domain = reduced.domain if tau else None
            for name, (commands, steps) in tests.items():
                solver = ReducedImplicitEuler(model, reduced.basis, domain, DT)
                try:
                    out = run(solver, solver.rest_state(), commands, steps)
                    entry[name] = compare(model, full[name], out)
                except DivergenceError as exc:
                    entry[name] = {"diverged": str(exc)}
            results["reduced"].append(entry)
            print(json.dumps(entry), flush=True)
            args.out.mkdir(parents=True, exist_ok=True)
            (args.out / f"multigait_{label}.json").write_text(json.dumps(results, indent=1))
    plot(results, args.out / f"multigait_{label}.png")


def plot(results: dict, path: Path) -> None:
    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    if not results["reduced"]:
        return
    for ax, key, ylabel in (
        (axes[0], "rms_error_pct_length", "RMS node error (% of length)"),
        (axes[1], "travel_error_pct", "travel error (%)"),
    ):
        for entry in results["reduced"]:
            gait = entry["gait"]
            if "diverged" in gait:
                continue
            speed = gait["steps_per_cpu_s"]
            ax.scatter(speed, gait[key], c="C0" if entry["tau"] else "C3")
            ax.annotate(f"{entry['modes']}m, tau {entry['tau']:g}", (speed, gait[key]), fontsize=7)
        ax.axvline(results["full_steps_per_cpu_s"]["gait"], color="0.5", ls="--", lw=0.8)
        ax.set_xscale("log")
        ax.set_xlabel("steps per CPU second (dashed: full FEM; red: every element)")
        ax.set_ylabel(ylabel)
    fig.suptitle(f"Reduced Multigait ({results['model']}) over the hand gait")
    fig.tight_layout()
    save_figure(fig, path, dpi=100)


if __name__ == "__main__":
    main()
