"""RodManipulator: how far each contact configuration turns the rod, and how far the two
re-contact experts chained by the configuration take it (thesis §4.2.3, Fig. 4.10: "rod
turned until stuck, expert trajectory reconfigures the contacts, continues to 280°"; issue 19).

    python experiments/graph/rod_experts.py [--steps 60] [--out experiments/results/graph]

Three open-loop programs on ``pliant graph train RodManipulator``'s scene (its environment,
graph and experts, `pliant.learn.graph.scenes.make_scene`), each for ``--steps`` steps:
``stroke only`` (the on-top expert repeated: the fingertips placed over the rod's axis from
the observed pose, pressed, dragged round), ``pinch only`` (the beside expert repeated), and
``chained`` (before each expert, the stroke while the rod's axis lies within ``--band`` degrees
of the fingers' line, y, where the fingertips can land on its top; the pinch otherwise).
Writes ``<out>/RodManipulator/<name>.json`` (angle and node after every step; ``--name``,
default ``experts``) and ``<name>.png``.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from pliant.learn.graph.rod import angle_rule, expert_rollout  # noqa: E402
from pliant.learn.graph.scenes import make_scene  # noqa: E402
from pliant.viz import save_figure


def replay(folder: Path) -> dict:
    """One greedy episode of a trained run (graph or plain SAC) on its scene (the 280° goal):
    the Evaluator's choices, the rod's angle after every step."""
    from pliant.learn.graph import GraphConfig
    from pliant.learn.graph.settings import CONFIGS, ENV_SETTINGS
    from pliant.learn.graph.training import build_learner

    scene = make_scene("RodManipulator", **ENV_SETTINGS["RodManipulator"])
    meta = json.loads((folder / "history.json").read_text())
    config = GraphConfig(**CONFIGS["RodManipulator"])
    agent = build_learner(meta["method"], scene, config, meta["seed"])
    agent.load(folder / "checkpoint.pt")
    angles, nodes = [], []
    env = scene.env
    step = env.step

    def recording(action):  # the angle and the node after every step of the episode
        out = step(action)
        angles.append(float(np.degrees(out[4]["angle"])))
        nodes.append(scene.graph.node_of(out[0]))
        return out

    env.step = recording
    start = time.perf_counter()
    episode = agent.run_episode(env, train=False, seed=10_000)
    names = scene.graph.names + [e.name for e in scene.experts]
    return {
        "method": meta["method"],
        "trained_steps": agent.steps,
        "experts": [names[c] for c in episode.get("choices", [])],
        "angle_deg": [0.0, *angles],
        "nodes": [scene.graph.node_of(env.reset(seed=10_000)[0]), *nodes],
        "max_angle_deg": max([0.0, *angles]),
        "final_angle_deg": angles[-1] if angles else 0.0,
        "return": episode["return"],
        "wall_s": time.perf_counter() - start,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--steps", type=int, default=60)
    parser.add_argument("--band", type=float, default=45.0, help="stroke within this (deg)")
    parser.add_argument("--out", type=Path, default=Path("experiments/results/graph"))
    parser.add_argument("--name", default="experts", help="writes <out>/RodManipulator/<name>.*")
    parser.add_argument(
        "--learned", type=Path, nargs="*", default=[],
        help="graph run folders (cartstem.py --scene RodManipulator) whose checkpoint to replay"
        " greedily on the 280° goal",
    )  # fmt: skip
    args = parser.parse_args()
    # No goal ends these runs early: the goal is put out of reach.
    scene = make_scene("RodManipulator", goal_low=4 * np.pi, goal_high=4 * np.pi)

    programs = {
        "stroke only": lambda obs: "stroke",
        "pinch only": lambda obs: "pinch",
        "chained": angle_rule(args.band),
    }
    results = {name: expert_rollout(scene, choose, args.steps) for name, choose in programs.items()}
    for folder in args.learned:
        run = replay(folder)
        results[f"{folder.name}, {run['trained_steps']} steps"] = run
    for name, r in results.items():
        reached = next((i for i, a in enumerate(r["angle_deg"]) if a >= 280.0), None)
        r["first_step_past_280_deg"] = reached
        print(f"{name}: max {r['max_angle_deg']:.1f} deg, past 280 at step {reached},"
              f" {r['wall_s']:.1f} s; experts {r['experts']}")  # fmt: skip
    root = args.out / "RodManipulator"
    root.mkdir(parents=True, exist_ok=True)
    meta = {
        "command": "python experiments/graph/rod_experts.py "
        f"--steps {args.steps} --band {args.band}"
        + "".join(f" --learned {folder}" for folder in args.learned)
        + (f" --name {args.name}" if args.name != "experts" else ""),
        "nodes": scene.graph.names,
        "thesis": "280 deg example (Fig. 4.10): contact, turn until stuck, expert re-contact,"
        " on to 280 deg; plain SAC cannot reconfigure the contacts within 2e5 iterations",
    }
    (root / f"{args.name}.json").write_text(json.dumps({**meta, "runs": results}, indent=1))
    fig, ax = plt.subplots(figsize=(6, 3.5))
    for name, r in results.items():
        ax.plot(r["angle_deg"], label=name)
    ax.axhline(280.0, color="k", lw=0.8, ls="--", label="thesis example, 280°")
    ax.set(xlabel="environment step (0.1 s)", ylabel="rod angle (deg)", title="RodManipulator")
    ax.legend()
    fig.tight_layout()
    save_figure(fig, root / f"{args.name}.png", dpi=120)


if __name__ == "__main__":
    main()
