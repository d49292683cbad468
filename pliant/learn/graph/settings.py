"""The graph studies' agent settings per scene (experiments/graph/: cartstem.py, swap.py,
rod_experts.py): the scenes' GraphConfig fields, their environments' keywords, the command-line
options the studies vary, and the run folders' labels they imply."""

from __future__ import annotations

import argparse

import numpy as np

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


def add_evaluator_options(parser: argparse.ArgumentParser) -> None:
    """The agents' settings that the graph studies vary (experiments/graph/cartstem.py and
    swap.py): the Evaluator's, and the internal agents' form."""
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
