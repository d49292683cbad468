"""``pliant graph train SCENE``: the configuration-space graph (or the plain-SAC baseline),
trained with checkpoints, resume and periodic evaluation (:mod:`pliant.learn.graph.training`)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console

from pliant.cli.options import Count, Seed, option
from pliant.cli.support import at_least_one, command_group, one_of, output_folder
from pliant.learn.graph.training import METHODS, SCENES, GraphSettingsError, train_run

app = command_group("Hierarchical RL over contact configurations (thesis §4.2).")
console = Console()


def settings_file(path: Path | None) -> dict:
    """Option callback: the JSON settings in `path` ({} without one); BadParameter if it cannot
    be read or is not a JSON object with only 'agent' and 'env' keys."""
    if path is None:
        return {}
    try:
        settings = json.loads(Path(path).read_text())
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise typer.BadParameter(f"cannot read JSON settings from {str(path)!r}: {exc}") from None
    if not isinstance(settings, dict) or set(settings) - {"agent", "env"}:
        raise typer.BadParameter(
            f"{str(path)!r} must hold a JSON object with 'agent' and/or 'env' keys"
        )
    return settings


@app.command()
def train(
    scene: Annotated[
        str,
        typer.Argument(
            help="Corridor, CartStemContact or RodManipulator", callback=one_of(*SCENES)
        ),
    ],
    config: Annotated[
        Path | None,
        option("JSON: {'agent': GraphConfig fields, 'env': environment keywords}", settings_file),
    ] = None,
    method: Annotated[
        str,
        option(
            "graph, convex (QP internal agents), convex_node (the QP kept inside its node) or sac",
            one_of(*METHODS),
        ),
    ] = "graph",
    steps: Annotated[int, option("environment steps in all", at_least_one)] = 20_000,
    seed: Seed = 0,
    eval_every: Annotated[int, option("steps between evaluations", at_least_one)] = 600,
    eval_episodes: Count = 5,
    out: Annotated[Path, option("run folder (checkpoint.pt, history.json)", output_folder)] = Path(
        "runs/graph"
    ),
    resume: Annotated[bool, typer.Option(help="continue the checkpoint in OUT")] = True,
) -> None:
    """Train SCENE's graph agents (or plain SAC) and evaluate them every EVAL_EVERY steps."""
    settings = config  # read and checked by settings_file
    try:
        history = train_run(
            scene, method, out, steps=steps, seed=seed, config=settings.get("agent"),
            env_kwargs=settings.get("env"), eval_every=eval_every, eval_episodes=eval_episodes,
            resume=resume,
        )  # fmt: skip
    except GraphSettingsError as exc:
        raise typer.BadParameter(str(exc)) from None
    if history:
        console.print(f"last evaluation: {history[-1]}")
