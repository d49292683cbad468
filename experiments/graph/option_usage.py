"""How a trained graph run spent its training steps: the share of environment steps taken by
internal agents (the Evaluator chose the node the state was in) and by external options or
experts, per node, over the whole run and its last steps; each kind of option's length and how
often it reached its node; and how the greedy hierarchy decides on the evaluation goals
(issue 19).

    python experiments/graph/option_usage.py RUN [RUN ...] [--last 5000] [--episodes 10]
        [--out experiments/results/graph/CartStemContact/option_usage.json]

RUN is a run folder of ``pliant graph train`` / cartstem.py (``checkpoint.pt`` and
``history.json``; the checkpoints are not committed: rerun the training command first). The
Evaluator's buffer holds one transition per environment step (Eq. 4.6 expands an option of T
steps into T transitions), with the node the option started in and the choice, so it counts
the steps of each kind; it holds the whole run while the run is shorter than the buffer.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from pliant import configure_threads
from pliant.learn.graph import GraphConfig
from pliant.learn.graph.scenes import make_scene
from pliant.learn.graph.training import build_learner


def options(buffer: dict, n_nodes: int) -> dict:
    """Per (node, choice) over the run: the steps, the options (each option's last transition
    has duration 1), their mean length, and the share that ended in the chosen node (a move)
    or left the node (an internal agent's)."""
    node, choice = buffer["node"].astype(int), buffer["choice"].astype(int)
    ends = buffer["duration"] == 1
    reached = buffer["next_node"].astype(int)
    out = {}
    for i in range(n_nodes):
        for j in np.unique(choice[node == i]).tolist():
            rows = (node == i) & (choice == j)
            last = rows & ends
            arrived = reached[last] == j if j != i else reached[last] != i
            out[f"{i}->{j}"] = {
                "steps": int(rows.sum()),
                "options": int(last.sum()),
                "mean_length": float(rows.sum() / max(last.sum(), 1)),
                "reached" if j != i else "left_node": float(arrived.mean()) if last.any() else None,
            }
    return out


def usage(buffer: dict, last: int, n_nodes: int) -> dict:
    node, choice = buffer["node"].astype(int), buffer["choice"].astype(int)
    internal = choice == node

    def share(rows: slice) -> dict:
        n, c, inside = node[rows], choice[rows], internal[rows]
        return {
            "steps": int(len(n)),
            "internal_share": float(inside.mean()) if len(n) else None,
            "per_node": {
                str(i): {
                    "steps": int((n == i).sum()),
                    "internal_share": float(inside[n == i].mean()) if (n == i).any() else None,
                    "choices": np.bincount(c[n == i], minlength=n_nodes).tolist(),
                }
                for i in range(n_nodes)
            },
        }

    return {
        "whole_run": share(slice(None)),
        f"last_{last}": share(slice(-last, None)),
        "options": options(buffer, n_nodes),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("runs", nargs="+", type=Path)
    parser.add_argument("--last", type=int, default=5000)
    parser.add_argument("--episodes", type=int, default=10)
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    configure_threads(torch_threads=1)
    report = {}
    for run in args.runs:
        meta = json.loads((run / "history.json").read_text())
        scene = make_scene(meta["scene"])
        agent = build_learner("graph", scene, GraphConfig(**meta["config"]), meta["seed"])
        agent.load(run / "checkpoint.pt")
        saved = agent.evaluator_buffer.state_dict()["data"]
        entry = usage(saved, args.last, agent.graph.n_nodes)
        entry["trained_steps"] = agent.steps
        entry["evaluator_temperature"] = agent.evaluator.temperature  # tuned or fixed
        # The greedy hierarchy on the evaluation goals (cartstem.py's: seeds 10 000 on).
        episodes = [
            agent.run_episode(scene.env, train=False, seed=10_000 + k) for k in range(args.episodes)
        ]
        entry["greedy"] = [
            {
                "success": bool(e["success"]),
                "return": e["return"],
                "length": e["length"],
                "nodes": e["nodes"],
                "choices": e["choices"],
            }
            for e in episodes
        ]
        report[str(run)] = entry
        print(run, json.dumps({k: v for k, v in entry.items() if k != "greedy"}, indent=1))
        for e in entry["greedy"]:
            print("  greedy:", e["success"], round(e["return"], 2), e["length"], e["choices"][:12])
    if args.out is not None:
        args.out.write_text(json.dumps(report, indent=1))


if __name__ == "__main__":
    main()
