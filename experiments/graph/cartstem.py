"""The configuration-space graph against plain SAC (thesis §4.2.3, Fig. 4.9A; issue 19).

    python experiments/graph/cartstem.py [--scene CartStemContact|RodManipulator|Corridor]
        [--methods graph convex convex_node sac]
        [--seeds 0 1 2] [--steps 250000] [--eval-every 600] [--out experiments/results/graph]
        [--obstacle-shift S]

Methods (same SAC and hyper-parameters for all, thesis L827): ``graph`` (node by Eq. 4.7,
Evaluator, external and internal SAC agents per node), ``convex`` (internal agents replaced by
the scene's convex controller run until the node changes; CartStemContact's: the FEM static
inverse), ``convex_node`` (that controller kept inside its node, ``Scene.node_controllers``),
``sac`` (plain SAC). Every run trains through ``pliant graph train``'s ``train_run``: a run
folder per (method, seed) holds its checkpoint and evaluation history, and rerunning the
script resumes each run up to ``--steps`` (a larger ``--steps`` continues the same runs;
``--steps 0`` only summarises them). Writes
``<out>/<scene>/summary.json``: per method and seed the first evaluated step with success ≥
``--solved`` ("iterations to solve"; ``_3``: of the sliding mean of 3 evaluations), its
steps, the mean success over all its evaluations (the area under its curve), its last
evaluation and the mean success and return of its last five, and whether a
budget is below the thesis' 250k (``partial``), over every run folder of the scene (not only
those this call trained); ``against_sac``: each method against plain SAC over the seeds,
per number, with a one-sided Mann–Whitney p-value (:func:`compare`); and a plot of the
learning curves (mean and min-max over seeds) and of the seeds' first crossings
(``first_crossings.png``). With
``--obstacle-shift S`` (CartStemContact) the obstacles move together by U(-S, S) mm each
episode, the cart drawn around them (the thesis' random contact and base positions); those
runs live in ``<out>/CartStemContact/shiftS/``.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from pliant import configure_threads  # noqa: E402
from pliant.learn.graph.settings import (  # noqa: E402
    ENV_SETTINGS,
    add_evaluator_options,
    agent_config,
    label_of,
    run_label,
)
from pliant.learn.graph.training import train_run  # noqa: E402
from pliant.viz import save_figure

THESIS = {
    "CartStemContact": {"sac": 140_000, "graph": 80_000, "convex": 40_000},
    "RodManipulator": "280 deg reached by the graph with experts; plain SAC cannot reconfigure"
    " the contacts within 200000 iterations",
}
THESIS_STEPS = 250_000
METHODS = ("graph", "convex", "convex_node", "sac")
#: Run folders and summary keys, in the plots' order: the methods, the graph with a shared
#: internal agent; a tuned Evaluator temperature adds ``_entropyF`` (:func:`label_of`).
LABELS = ("graph", "graph_shared", "convex", "convex_node", "sac")


def first_solved(history: list[dict], solved: float, window: int = 1) -> int | None:
    """The first evaluated step where the mean success of the `window` evaluations ending
    there reaches `solved` (a sliding average, as the thesis' curves are)."""
    success = [h["success"] for h in history]
    return next(
        (
            h["steps"]
            for k, h in enumerate(history)
            if k + 1 >= window and np.mean(success[k + 1 - window : k + 1]) >= solved
        ),
        None,
    )


#: Per-seed numbers compared against the baseline: (summary key, which way is better).
COMPARED = (
    ("iterations_to_solve", "less"),
    ("iterations_to_solve_3", "less"),
    ("mean_success", "greater"),
    ("last5_success", "greater"),
)


def baseline_of(label: str, labels) -> str:
    """The plain-SAC runs a label is compared with: SAC under the same schedule where there
    is one (``graph_episode5`` against ``sac_episode5``), plain ``sac`` otherwise."""
    twin = "sac" + label[label.index("_") :] if "_" in label else "sac"
    return twin if twin in labels else "sac"


def compare(runs: dict) -> dict:
    """Each method against its plain-SAC baseline (:func:`baseline_of`) over seeds, per number
    of :data:`COMPARED`: how many seeds, how many never reached the success (`censored`), the
    mean over those that did, and the one-sided Mann–Whitney p-value of the method being
    better (scipy's exact test for small samples). A run that never reached the success ranks
    after every run that did, which holds only where its budget is past every crossing of
    both methods; otherwise, and for the areas and last evaluations between runs of different
    budgets, the number is not compared."""
    from scipy.stats import mannwhitneyu

    def values(label: str, key: str) -> tuple[np.ndarray, list[int]]:
        seeds = runs[label].values()
        found = [run["last5"]["success"] if key == "last5_success" else run[key] for run in seeds]
        return np.array([np.inf if v is None else v for v in found], float), [
            run["steps"] for run in seeds
        ]

    result = {}
    for label in runs:
        baseline = baseline_of(label, runs)
        if label.startswith("sac") or baseline not in runs:
            continue
        rows = {}
        for key, better in COMPARED:
            (x, x_steps), (y, y_steps) = values(label, key), values(baseline, key)
            both, steps = np.r_[x, y], np.array(x_steps + y_steps, float)
            if key.startswith("iterations"):
                censored = steps[np.isinf(both)]
                comparable = censored.min(initial=np.inf) >= both[np.isfinite(both)].max(initial=0)
            else:  # runs stop at the first episode's end past their budget
                comparable = steps.max() <= 1.05 * steps.min()
            if not comparable or len(x) < 2 or len(y) < 2:
                continue
            rows[key] = {
                "better": better,
                "n": [len(x), len(y)],
                "censored": [int(np.isinf(x).sum()), int(np.isinf(y).sum())],
                "mean_reached": [
                    float(v[np.isfinite(v)].mean()) if np.isfinite(v).any() else None
                    for v in (x, y)
                ],
                "p_one_sided": float(mannwhitneyu(x, y, alternative=better).pvalue),
            }
        result[label] = {"baseline": baseline, **rows}
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scene", default="CartStemContact")
    parser.add_argument(
        "--methods", nargs="*", default=["graph", "convex", "sac"],
        help="methods to train (none: only summarise the run folders there)",
    )  # fmt: skip
    parser.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2])
    parser.add_argument("--steps", type=int, default=THESIS_STEPS)
    parser.add_argument("--eval-every", type=int, default=600)
    parser.add_argument("--eval-episodes", type=int, default=5)
    parser.add_argument("--solved", type=float, default=0.8, help="success rate that counts")
    parser.add_argument("--out", type=Path, default=Path("experiments/results/graph"))
    parser.add_argument(
        "--obstacle-shift", type=float, default=0.0,
        help="CartStemContact: move both obstacles by U(-S, S) mm each episode (obstacle_shift)",
    )  # fmt: skip
    add_evaluator_options(parser)
    args = parser.parse_args()
    configure_threads(torch_threads=1)
    root = args.out / args.scene
    env_kwargs = dict(ENV_SETTINGS.get(args.scene, {}))
    if args.obstacle_shift:
        if args.scene != "CartStemContact":
            parser.error("--obstacle-shift is CartStemContact's")
        env_kwargs["obstacle_shift"] = args.obstacle_shift
        root = root / f"shift{args.obstacle_shift:g}"
    config = agent_config(args)
    runs = {}
    for method in args.methods:
        for seed in args.seeds:
            name = run_label(method, args)
            runs[name, seed] = train_run(
                args.scene, method, root / f"{name}_seed{seed}", steps=args.steps, seed=seed,
                config=config, env_kwargs=env_kwargs,
                eval_every=args.eval_every, eval_episodes=args.eval_episodes,
            )  # fmt: skip
    # The summary covers every run folder of the scene, whichever this call trained, each
    # with the settings it was trained with.
    configs = {key: config for key in runs}
    for folder in sorted(root.glob("*_seed*")):
        label, _, seed = folder.name.rpartition("_seed")
        if not ((folder / "history.json").exists() and seed.isdigit()):
            continue
        saved = json.loads((folder / "history.json").read_text())
        # Only folders named by their own settings (not, e.g., convex_closed_form_seed0).
        if label_of(saved.get("method", label), saved.get("config", {})) == label:
            runs.setdefault((label, int(seed)), saved["evaluations"])
            configs[label, int(seed)] = saved.get("config", {})
    labels = {key[0] for key in runs}
    methods = [m for m in LABELS if m in labels] + sorted(labels - set(LABELS))
    summary = {
        "scene": args.scene,
        "partial": any(h and h[-1]["steps"] < THESIS_STEPS for h in runs.values()),
        "solved_success": args.solved,
        "config": config,
        "env": env_kwargs,
        "thesis": THESIS.get(args.scene),
        "runs": {
            method: {
                str(seed): {
                    "steps": history[-1]["steps"] if history else 0,
                    "iterations_to_solve": first_solved(history, args.solved),
                    "iterations_to_solve_3": first_solved(history, args.solved, window=3),
                    # the mean success over every evaluation: the area under the learning
                    # curve, a measure of speed less noisy than a first crossing
                    "mean_success": float(np.mean([h["success"] for h in history]))
                    if history
                    else None,
                    "last": history[-1] if history else None,
                    # the last five evaluations' means: single evaluations are noisy
                    "last5": {
                        key: float(np.mean([h[key] for h in history[-5:]]))
                        for key in ("success", "return")
                    }
                    if history
                    else None,
                    "config": configs[m, seed],
                }
                for (m, seed), history in sorted(runs.items())
                if m == method
            }
            for method in methods
        },
    }
    summary["against_sac"] = compare(summary["runs"])
    (root / "summary.json").write_text(json.dumps(summary, indent=1))
    # Evaluation return and success, and RodManipulator's final angle (its result).
    keys = ["return", "success"] + (["final_angle"] if args.scene == "RodManipulator" else [])
    fig, axes = plt.subplots(1, len(keys), figsize=(6 * len(keys), 3.5), squeeze=False)
    for ax, key in zip(axes[0], keys, strict=True):
        for method in methods:
            curves = [h for (m, _), h in sorted(runs.items()) if m == method and h]
            if not curves:
                continue
            n = min(len(c) for c in curves)
            steps = np.array([h["steps"] for h in curves[0][:n]])
            values = np.array([[h.get(key, np.nan) for h in c[:n]] for c in curves])
            if key == "final_angle":
                values = np.degrees(values)
            ax.plot(steps, values.mean(0), label=f"{method} ({len(curves)} seeds)")
            ax.fill_between(steps, values.min(0), values.max(0), alpha=0.2)
        label = {"final_angle": "final rod angle (deg)", "success": "evaluation success rate"}
        label = label.get(key, "evaluation return")
        ax.set(xlabel="environment steps", ylabel=label, title=args.scene)
        ax.legend()
    fig.tight_layout()
    save_figure(fig, root / "curves.png", dpi=120)
    # The seeds' first crossings as a step function: the share of a method's seeds that have
    # reached the success by each step (a seed that never does keeps the curve below 1).
    fig, ax = plt.subplots(figsize=(6, 3.5))
    for method in methods:
        seeds = [run for run in summary["runs"][method].values() if run["last"]]
        if not seeds:
            continue
        crossings = [run["iterations_to_solve"] for run in seeds]
        reached = np.sort([c for c in crossings if c is not None])
        shares = np.arange(len(reached) + 1) / len(crossings)
        budget = max(run["steps"] for run in seeds)  # the curve runs to the budget
        ax.step(np.r_[0, reached, budget], np.r_[shares, shares[-1]], where="post",
                label=f"{method} ({len(reached)} of {len(crossings)} seeds)")  # fmt: skip
    ax.set(xlabel="environment steps", ylabel=f"seeds with an evaluation ≥ {args.solved:g}",
           title=args.scene, ylim=(0, 1.05))  # fmt: skip
    ax.legend(loc="lower right", fontsize="small")
    fig.tight_layout()
    save_figure(fig, root / "first_crossings.png", dpi=120)
    print(json.dumps(summary["runs"], indent=1))


if __name__ == "__main__":
    main()
