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
import torch  # noqa: E402

from pliant.learn.graph.training import train_run  # noqa: E402

CONFIGS = {
    # D.2's settings, hidden layers 256 (the authors: 512) for the CPU.
    "CartStemContact": {"hidden": 256, "lr": 3e-4, "batch_size": 256, "learning_starts": 500},
    # The tests' settings.
    "Corridor": {"hidden": 64, "d": 16, "lr": 1e-3, "batch_size": 64, "learning_starts": 200,
                 "option_limit": 20},
    # CartStemContact's.
    "RodManipulator": {"hidden": 256, "lr": 3e-4, "batch_size": 256, "learning_starts": 500},
}  # fmt: skip
#: Environment settings: RodManipulator's goal is the thesis' example, 280°.
ENV_SETTINGS = {
    "RodManipulator": {"goal_low": float(np.radians(280.0)), "goal_high": float(np.radians(280.0))}
}
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


def add_evaluator_options(parser: argparse.ArgumentParser) -> None:
    """The agents' settings that the experiments vary (this script and swap.py): the
    Evaluator's, and the internal agents' form."""
    parser.add_argument(
        "--internal", choices=["per_node", "shared"], default="per_node",
        help="the learned internal agents: one SAC per node (the thesis'), or one SAC on"
        " [s | one-hot(node)] for all (GraphConfig.internal); 'shared' runs are kept as"
        " graph_shared_seedN",
    )  # fmt: skip
    parser.add_argument(
        "--evaluator-target", choices=["max", "soft"], default="max",
        help="the Evaluator's bootstrap (GraphConfig.evaluator_target); 'soft' gave the"
        " results committed before 2026-11-26",
    )  # fmt: skip
    parser.add_argument(
        "--evaluator-temperature", type=float, default=None,
        help="the Evaluator's sampling temperature in training (GraphConfig's default: 0.5)",
    )  # fmt: skip
    parser.add_argument(
        "--evaluator-entropy", type=float, default=None,
        help="tune the Evaluator's temperature to keep this fraction of the uniform choice's"
        " entropy (GraphConfig.evaluator_entropy); runs kept as graph_entropyF_seedN",
    )  # fmt: skip
    parser.add_argument(
        "--updates-per-episode", type=int, default=None,
        help="the authors' schedule: this many gradient steps of every agent after each"
        " episode, none during it (GraphConfig.updates_per_episode; plain SAC too); runs kept"
        " as METHOD_episodeK_seedN",
    )  # fmt: skip
    parser.add_argument(
        "--update-scope", choices=["node", "internal", "all"], default="node",
        help="the agents a per-step update trains: the node's (the default), every node's"
        " internal agent and the node's external one, or every one (GraphConfig.update_scope);"
        " runs kept as METHOD_internal_seedN, METHOD_all_seedN",
    )  # fmt: skip
    parser.add_argument(
        "--avoid-cycles", action="store_true",
        help="train and evaluate with the Evaluator kept off a loop it has closed within an"
        " episode (GraphConfig.avoid_cycles); runs kept as METHOD_avoid_seedN",
    )  # fmt: skip


def agent_config(args: argparse.Namespace) -> dict:
    """The scene's GraphConfig fields with the Evaluator options of the command line."""
    config = {**CONFIGS[args.scene], "evaluator_target": args.evaluator_target}
    if args.internal != "per_node":
        config["internal"] = args.internal
    if args.evaluator_temperature is not None:
        config["evaluator_temperature"] = args.evaluator_temperature
    if args.evaluator_entropy is not None:
        config["evaluator_entropy"] = args.evaluator_entropy
    if args.updates_per_episode is not None:
        config["updates_per_episode"] = args.updates_per_episode
    if args.update_scope != "node":
        config["update_scope"] = args.update_scope
    if args.avoid_cycles:
        config["avoid_cycles"] = True
    return config


def label_of(method: str, config: dict) -> str:
    """A run's folder prefix from its method and agent settings: the method, ``_shared`` for
    a shared internal agent, ``_entropyF`` for an Evaluator temperature tuned to F (the
    graph's), ``_avoid`` for an Evaluator kept off the loops it closes (a hierarchy's),
    ``_all`` (``_internal``) for every agent (internal agent) updated at each step (a
    hierarchy's), ``_episodeK`` for K
    updates after each episode (any method's)."""
    per_episode = config.get("updates_per_episode")
    schedule = f"_episode{per_episode}" if per_episode else ""
    if method != "sac" and config.get("update_scope", "node") != "node":
        schedule = f"_{config['update_scope']}" + schedule
    if method != "sac" and config.get("avoid_cycles"):
        schedule = "_avoid" + schedule
    if method != "graph":
        return method + schedule
    label = method + ("_shared" if config.get("internal") == "shared" else "")
    entropy = config.get("evaluator_entropy")
    return label + (f"_entropy{entropy:g}" if entropy is not None else "") + schedule


def run_label(method: str, args: argparse.Namespace) -> str:
    """The folder prefix of a run this command trains."""
    return label_of(method, agent_config(args))


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
    torch.set_num_threads(1)
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
    fig.savefig(root / "curves.png", dpi=120)
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
    fig.savefig(root / "first_crossings.png", dpi=120)
    print(json.dumps(summary["runs"], indent=1))


if __name__ == "__main__":
    main()
