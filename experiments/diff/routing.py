"""Cable routing design on the Soft Finger: L-BFGS-B on the exact gradient against
derivative-free search (Nelder-Mead, Optuna TPE), counted in equilibria solved.

    python experiments/diff/routing.py [--resolution coarse] [--lbfgs 40] [--budget 200]
        [--out experiments/results/diff/routing.json] [--resume]

The coarse Finger (1610 tetrahedra, no gravity; pliant.diff.scenes.routing_finger) with its
closing cable only, shortened by 8 mm (displacement mode): the design is the (x, z) of the
cable's six routing points, each in the half of its phalanx it starts in, less 1 mm (12
coordinates; y stays on the mid-plane), the objective the fingertip's reach: how far it
comes down (-z) at the static equilibrium. Every method starts from the Finger's own routing
(z = 2 mm, 8 mm below mid-height) and is charged one equilibrium (StaticSolver from rest)
per evaluation; L-BFGS-B's evaluations also take the adjoint (pliant.diff.design.
RoutingDesign), whose wall time the JSON reports beside the solves. An equilibrium that fails
counts as reach 0.

Writes the JSON and a PNG beside it (best reach against equilibria solved; the routings found)
and, per method, the equilibria it spent to bring the tip down --target mm (70 by default).
Each method's result is saved as it ends: --resume skips those already in the file. Wall
times are on the shared 2-core machine under other jobs' load.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import matplotlib
import numpy as np
import optuna

from pliant.diff.design import DesignResult, RoutingDesign, optimise_routing
from pliant.diff.scenes import routing_finger
from pliant.errors import DivergenceError
from pliant.robots.finger import soft_finger
from pliant.viz import save_figure

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
OUT = ROOT / "experiments" / "results" / "diff" / "routing.json"


def tpe(design: RoutingDesign, lower, upper, budget: int, seed: int = 0) -> DesignResult:
    """Optuna's TPE, the Finger's own routing enqueued as its first trial."""
    out = DesignResult(design.initial.copy(), 0.0)
    names = [f"t{i}" for i in range(design.initial.size)]
    start = design.solves

    def objective(trial):
        theta = np.array(
            [trial.suggest_float(n, lo, hi) for n, lo, hi in zip(names, lower, upper, strict=True)]
        )
        try:
            value = design.reach(theta)
        except DivergenceError:
            design.solves += 1
            out.failed += 1
            value = 0.0
        out.history.append((design.solves - start, value))
        if value > out.reach:
            out.theta, out.reach = theta, value
        return value

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    study = optuna.create_study(direction="maximize", sampler=optuna.samplers.TPESampler(seed=seed))
    study.enqueue_trial(dict(zip(names, design.initial, strict=True)))
    study.optimize(objective, n_trials=budget)
    out.solves = design.solves - start
    return out


def summary(result: DesignResult, design: RoutingDesign, seconds: float, at: int) -> dict:
    best = np.maximum.accumulate([r for _, r in result.history])
    within = [b for (n, _), b in zip(result.history, best, strict=True) if n <= at]
    return {
        "reach_mm": result.reach,
        "solves": result.solves,
        "adjoints": result.adjoints,
        "failed": result.failed,
        "seconds": seconds,
        f"reach_within_{at}_solves_mm": within[-1] if within else 0.0,
        "history": [[int(n), float(b)] for (n, _), b in zip(result.history, best, strict=True)],
        "routing": design.points(result.theta)[design.rows].tolist(),
    }


def figure(out: dict, path: Path) -> None:
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(11, 4))
    for name, res in out["methods"].items():
        h = np.array(res["history"])
        ax.step(h[:, 0], h[:, 1], where="post", label=f"{name}: {res['reach_mm']:.1f} mm")
        p = np.array(res["routing"])
        bx.plot(p[:, 0], p[:, 2], "o-", label=name)
    p0 = np.array(out["initial_routing"])
    bx.plot(p0[:, 0], p0[:, 2], "k--", label="the Finger's routing")
    for n in range(3):
        bx.add_patch(plt.Rectangle((52 * n, 0), 40, 20, fill=False, color="0.6"))
    ax.set_xlabel("equilibria solved")
    ax.set_ylabel("best reach: fingertip's drop (mm)")
    ax.set_title(f"reach for {out['pull_mm']:.0f} mm of cable")
    ax.legend()
    bx.set_xlabel("x (mm)")
    bx.set_ylabel("z (mm)")
    bx.set_title("closing cable's routing points (phalanges in grey)")
    bx.set_aspect("equal")
    bx.set_ylim(-2.0, 40.0)
    bx.legend(fontsize=7, loc="upper center", ncols=2)
    fig.tight_layout()
    save_figure(fig, path, dpi=110)
    plt.close(fig)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--resolution", default="coarse")
    parser.add_argument("--lbfgs", type=int, default=40, help="L-BFGS-B's equilibria")
    parser.add_argument("--budget", type=int, default=200, help="each derivative-free method's")
    parser.add_argument("--out", type=Path, default=OUT)
    parser.add_argument("--resume", action="store_true")
    parser.add_argument("--target", type=float, default=70.0, help="tip drop to count solves to")
    args = parser.parse_args()
    model, commands, free, lower, upper = routing_finger(
        soft_finger(resolution=args.resolution, gravity=(0.0, 0.0, 0.0))
    )
    out = {
        "resolution": args.resolution,
        "tetrahedra": model.body.n_elements,
        "pull_mm": float(commands[0]),
        "lbfgs_solves": args.lbfgs,
        "budget": args.budget,
        "methods": {},
    }
    if args.resume and args.out.exists():
        saved = json.loads(args.out.read_text())
        if all(saved.get(k) == out[k] for k in ("resolution", "lbfgs_solves", "budget")):
            out = saved
    design = RoutingDesign(model, "cable_0", commands, free=free)
    out["initial_reach_mm"] = design.reach(design.initial)
    out["initial_routing"] = design.points(design.initial)[design.rows].tolist()
    runs = {
        "L-BFGS-B + adjoint": lambda: optimise_routing(
            design, lower, upper, method="L-BFGS-B", max_solves=args.lbfgs
        ),
        "Nelder-Mead": lambda: optimise_routing(
            design, lower, upper, method="Nelder-Mead", max_solves=args.budget
        ),
        "Optuna TPE": lambda: tpe(design, lower, upper, args.budget),
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    for name, run in runs.items():
        if name in out["methods"]:
            continue
        began = time.perf_counter()
        result = run()
        out["methods"][name] = summary(result, design, time.perf_counter() - began, args.lbfgs)
        print(f"{name}: reach {result.reach:.2f} mm, {result.solves} solves", flush=True)
        args.out.write_text(json.dumps(out, indent=1) + "\n")
    out["target_mm"] = args.target
    for res in out["methods"].values():  # equilibria spent to reach the target drop
        reached = [n for n, best in res["history"] if best >= args.target]
        res["solves_to_target"] = reached[0] if reached else None
    args.out.write_text(json.dumps(out, indent=1) + "\n")
    figure(out, args.out.with_suffix(".png"))


if __name__ == "__main__":
    main()
