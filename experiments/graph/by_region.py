"""Where the trained CartStemContact learners succeed: goals a free beam reaches against goals
that need a contact (issue 19).

    python experiments/graph/by_region.py RUN [RUN ...] [--episodes 50] [--out FILE.json]

Each RUN is a run folder of ``cartstem.py`` (``checkpoint.pt`` and ``history.json``, which
give the method, seed, agent settings and environment keywords). Its checkpoint plays
``--episodes`` greedy episodes on goals of seeds 20 000 + k (not the training evaluations'
10 000 + k), and each episode is put in a region by its goal and the episode's obstacles:
``free`` when the goal lies in Eq. 4.7's no-contact interval of the cart (the straight beam's
tip is over the cart, so a free beam reaches it), ``contact`` otherwise (the beam must press
on an obstacle, or bend over one, to put its tip there). Writes, per run and region, the
number of goals, the success rate and the mean return and final distance, and the same over
the runs of each label (the folder's name before ``_seedN``: ``graph``, ``graph_avoid``,
``sac``). ``--reachable`` adds, per goal, how close the beam's tip gets to it
at static equilibrium over the cart's whole course (the FEM static inverse's continuation
sweep from the episode's start, 1 mm steps, then its Gauss-Newton; contacts included), so
that goals no static cart position reaches can be told from goals a learner misses.
``--avoid-cycles`` plays a hierarchy with its Evaluator kept off the loops it closes
(``GraphConfig.avoid_cycles``, as trained otherwise); a run trained with it plays with it.
"""

from __future__ import annotations

import argparse
import json
from collections import defaultdict
from pathlib import Path

import numpy as np

from pliant import configure_threads
from pliant.learn.graph import GraphConfig
from pliant.learn.graph.scenes import CartStemStaticInverse, make_scene
from pliant.learn.graph.training import build_learner


def region(env) -> str:
    """``free`` or ``contact`` for the goal of the episode `env` played last (Eq. 4.7)."""
    base = env.unwrapped
    half_diagonal = 0.5 * np.hypot(base.obstacle_size[0], base.obstacle_size[2])
    low = base.obstacles[0, 0] + half_diagonal
    high = base.obstacles[1, 0] - half_diagonal
    return "free" if low < base.task["goal"] < high else "contact"


def means(episodes: list[dict]) -> dict:
    return {
        "goals": len(episodes),
        "success": float(np.mean([e["success"] for e in episodes])) if episodes else None,
        "return": float(np.mean([e["return"] for e in episodes])) if episodes else None,
        "final_distance": float(np.mean([e["distance"] for e in episodes])) if episodes else None,
    }


def static_reach(env, inverse: CartStemStaticInverse, seed: int) -> float:
    """How close (mm) the tip gets to the goal of episode `seed` at static equilibrium, the
    cart anywhere on its course."""
    env.reset(seed=seed)
    base = env.unwrapped
    goal = base.task["goal"]
    cart = inverse.target(goal, sweep=1.0)
    found = inverse.equilibrium(cart, base.state.positions)
    return float("inf") if found is None else abs(found[0] - goal)


def play(run: Path, episodes: int, reachable: bool = False, avoid_cycles: bool = False) -> dict:
    """The run's greedy episodes' means by region, and whether its Evaluator avoided cycles
    (asked, or as trained)."""
    meta = json.loads((run / "history.json").read_text())
    scene = make_scene(meta["scene"], **meta.get("env", {}))
    avoid_cycles = avoid_cycles or meta["config"].get("avoid_cycles", False)
    config = GraphConfig(**{**meta["config"], "avoid_cycles": avoid_cycles})
    learner = build_learner(meta["method"], scene, config, meta["seed"])
    learner.load(run / "checkpoint.pt")
    inverse = CartStemStaticInverse(scene.env) if reachable else None
    played = defaultdict(list)
    for k in range(episodes):
        result = learner.run_episode(scene.env, train=False, seed=20_000 + k)
        name = region(scene.env)
        episode = {**result, "distance": float(result["info"]["distance"])}
        if inverse is not None:
            episode["static_reach"] = static_reach(scene.env, inverse, 20_000 + k)
        played[name].append(episode)
    steps = meta["evaluations"][-1]["steps"] if meta["evaluations"] else 0
    report = {name: means(played[name]) for name in ("free", "contact")}
    if inverse is not None:  # the goals a static cart position puts the tip within 1 mm of
        tolerance = scene.env.unwrapped.goal_tolerance
        for name in ("free", "contact"):
            reached = [e for e in played[name] if e["static_reach"] < tolerance]
            report[name]["statically_reachable"] = means(reached)
            report[name]["static_reach"] = [e["static_reach"] for e in played[name]]
    return {"seed": meta["seed"], "steps": steps, "avoid_cycles": avoid_cycles, **report}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("runs", nargs="+", type=Path)
    parser.add_argument("--episodes", type=int, default=50)
    parser.add_argument("--out", type=Path, default=None)
    parser.add_argument("--reachable", action="store_true", help="add each goal's static reach")
    parser.add_argument("--avoid-cycles", action="store_true", help="GraphConfig.avoid_cycles")
    args = parser.parse_args()
    configure_threads(torch_threads=1)
    runs, by_label = {}, defaultdict(list)
    for run in args.runs:
        report = play(run, args.episodes, args.reachable, args.avoid_cycles)
        runs[run.name] = report
        # grouped by the run folder's label (graph, graph_avoid, sac...), not only its method
        by_label[run.name.rpartition("_seed")[0] or run.name].append(report)
        print(run.name, json.dumps(report))
    summary = {
        label: {
            name: {
                key: float(np.mean([r[name][key] for r in reports if r[name][key] is not None]))
                for key in ("success", "return", "final_distance")
            }
            | {"goals": int(sum(r[name]["goals"] for r in reports))}
            for name in ("free", "contact")
        }
        for label, reports in by_label.items()
    }
    out = {
        "avoid_cycles": args.avoid_cycles,
        "episodes": args.episodes,
        "goal_seeds": "20000 + k",
        "runs": runs,
        "methods": summary,
    }
    print(json.dumps(summary, indent=1))
    if args.out is not None:
        args.out.write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
