"""Trained internal agents swapped for convex optimisation (thesis §4.2.3, L863: the
cumulative reward changes by 0.64 %; issue 19).

    python experiments/graph/swap.py [--scene CartStemContact] [--seed 0] [--steps 6000]
        [--episodes 20] [--out experiments/results/graph]

Trains (or resumes, up to ``--steps``) the graph method with learned internal agents in
``<out>/<scene>/graph_seed<seed>`` through ``pliant graph train``'s ``train_run`` and
cartstem.py's settings, then evaluates its checkpoint greedily on ``--episodes`` goals twice:
as trained, and with every internal agent replaced by the scene's convex controller
(``GraphAgent.swap_internal``; the Evaluator and the external agents as trained). Writes
``<out>/<scene>/swap_seed<seed>.json`` (``swap_shared_seed<seed>.json`` with ``--internal
shared``): both mean returns and success rates and the relative change of the return, and
each goal's episode under both (``episodes``: return, length, success, final distance, the
nodes visited and the Evaluator's choices), so that the change can be traced to the goals
where it happens; and once more with the controllers acting on across node changes
(``GraphConfig.controller_crosses``: ``convex_internal_crossing``), with the controllers
kept inside their node (``Scene.node_controllers``, where the scene has them:
``convex_in_node``), and each of these
once more with the Evaluator kept off a loop it has closed (``GraphConfig.avoid_cycles``:
``*_avoiding_cycles``); ``variants`` holds every one's means. ``--finetune N`` then
trains the swapped hierarchy (the Evaluator and the external agents, around the convex
internal agents) for N more environment steps and evaluates it on the same goals again
(``convex_internal_finetuned``; the checkpoint is left as trained).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
from pathlib import Path

from pliant import configure_threads
from pliant.learn.graph import GraphConfig
from pliant.learn.graph.hierarchy import episode_means
from pliant.learn.graph.scenes import make_scene
from pliant.learn.graph.settings import (
    ENV_SETTINGS,
    add_evaluator_options,
    agent_config,
    run_label,
)
from pliant.learn.graph.training import build_learner, train_run


def greedy_episodes(agent, env, episodes: int, seed: int = 10_000) -> tuple[dict, list[dict]]:
    """``agent.evaluate``'s means (the same goals, seeds ``seed + k``) and each episode."""
    runs = [agent.run_episode(env, train=False, seed=seed + k) for k in range(episodes)]
    each = [
        {
            "return": r["return"],
            "length": r["length"],
            "success": bool(r["success"]),
            "final_distance": r["info"].get("distance"),
            "nodes": [int(n) for n in r["nodes"]],
            "choices": [int(c) for c in r["choices"]],
        }
        for r in runs
    ]
    return episode_means(runs), each


def relative(variant: dict, reference: dict) -> float:
    """The relative change of the mean return from ``reference`` to ``variant``."""
    return (variant["return"] - reference["return"]) / abs(reference["return"])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scene", default="CartStemContact")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--steps", type=int, default=6000)
    parser.add_argument("--eval-every", type=int, default=600)
    parser.add_argument("--episodes", type=int, default=20)
    parser.add_argument("--out", type=Path, default=Path("experiments/results/graph"))
    parser.add_argument("--finetune", type=int, default=0, help="steps trained after the swap")
    add_evaluator_options(parser)
    args = parser.parse_args()
    configure_threads(torch_threads=1)
    config = agent_config(args)
    env_kwargs = ENV_SETTINGS.get(args.scene, {})
    root = args.out / args.scene
    name = run_label("graph", args)
    run = root / f"{name}_seed{args.seed}"
    history = train_run(
        args.scene, "graph", run, steps=args.steps, seed=args.seed, config=config,
        env_kwargs=env_kwargs, eval_every=args.eval_every,
    )  # fmt: skip
    scene = make_scene(args.scene, **env_kwargs)
    if not scene.controllers:
        raise SystemExit(f"{args.scene} has no convex internal agents to swap in")
    agent = build_learner("graph", scene, GraphConfig(**config), args.seed)
    agent.load(run / "checkpoint.pt")
    means, each = {}, {}  # variant -> greedy means, each goal's episode

    def evaluate(label: str, **flags) -> None:
        """Greedy episodes under ``label``, with these GraphConfig flags for the time."""
        saved = agent.config
        agent.config = dataclasses.replace(saved, **flags)
        means[label], each[label] = greedy_episodes(agent, scene.env, args.episodes)
        agent.config = saved

    # Every variant once more with the Evaluator kept off a loop it has closed
    # (GraphConfig.avoid_cycles).
    evaluate("learned_internal")
    evaluate("learned_internal_avoiding_cycles", avoid_cycles=True)
    agent.swap_internal(scene.controllers)
    evaluate("convex_internal")
    evaluate("convex_internal_avoiding_cycles", avoid_cycles=True)
    # The same controllers left to act across node changes (GraphConfig.controller_crosses).
    evaluate("convex_internal_crossing", controller_crosses=True)
    evaluate("convex_internal_crossing_avoiding_cycles", controller_crosses=True, avoid_cycles=True)
    if scene.node_controllers:  # controllers kept inside their node (Scene.node_controllers)
        agent.swap_internal(scene.node_controllers)
        evaluate("convex_in_node")
        evaluate("convex_in_node_avoiding_cycles", avoid_cycles=True)
        agent.swap_internal(scene.controllers)
    learned, convex, crossing = (
        means[k] for k in ("learned_internal", "convex_internal", "convex_internal_crossing")
    )

    def with_changes(label: str) -> dict:
        """A variant's means, and the relative change of its return on the learned agents as
        trained and on the learned agents under the same acting rule (avoiding cycles or not)."""
        same = "learned_internal" + (
            "_avoiding_cycles" if label.endswith("_avoiding_cycles") else ""
        )
        return {
            **means[label],
            "relative_return_change": relative(means[label], learned),
            "relative_return_change_same_rule": relative(means[label], means[same]),
        }

    change = (convex["return"] - learned["return"]) / abs(learned["return"])
    tuned = None
    if args.finetune > 0:  # the Evaluator and external agents learn around the controllers
        start = agent.steps
        while agent.steps - start < args.finetune:
            agent.run_episode(scene.env, train=True)
        tuned = agent.evaluate(scene.env, args.episodes)
    result = {
        "command": f"python experiments/graph/swap.py --scene {args.scene} --seed {args.seed}"
        f" --steps {args.steps} --episodes {args.episodes} --finetune {args.finetune}"
        f" --evaluator-target {args.evaluator_target} --internal {args.internal}"
        + (
            f" --evaluator-entropy {args.evaluator_entropy}"
            if args.evaluator_entropy is not None
            else ""
        )
        + (
            f" --evaluator-temperature {args.evaluator_temperature}"
            if args.evaluator_temperature is not None
            else ""
        ),
        "trained_steps": history[-1]["steps"] if history else agent.steps,
        "learned_internal": learned,
        "convex_internal": convex,
        "relative_return_change": float(change),
        "convex_internal_crossing": crossing,
        "relative_return_change_crossing": (crossing["return"] - learned["return"])
        / abs(learned["return"]),
        "variants": {label: with_changes(label) for label in means},
        "finetune_steps": args.finetune,
        "convex_internal_finetuned": tuned,
        "relative_return_change_finetuned": None
        if tuned is None
        else (tuned["return"] - learned["return"]) / abs(learned["return"]),
        "thesis_relative_return_change": 0.0064,
        "episodes": each,
    }
    suffix = name.removeprefix("graph")  # swap_seedN.json: per-node agents, fixed τ
    tag = f"_finetune{args.finetune}" if args.finetune else ""
    (root / f"swap{suffix}{tag}_seed{args.seed}.json").write_text(json.dumps(result, indent=1))
    print(json.dumps(result, indent=1))


if __name__ == "__main__":
    main()
