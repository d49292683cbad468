"""``pliant bench``: the engine's speed beside SOFA's figures, and with its options the
environments', the learner's and a rollout gradient's (:mod:`pliant.bench`)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console

from pliant.cli.options import option
from pliant.cli.support import at_least_one, numbers_list, output_file

console = Console()


def bench(
    meshes: Annotated[
        Path | None,
        typer.Option(help="folder of the reference SOFA meshes", exists=True, file_okay=False),
    ] = None,
    repeats: Annotated[int, option("timed repeats per scene (median reported)", at_least_one)] = 3,
    steps: Annotated[
        int, option("steps per timed repeat (scaled down for big scenes)", at_least_one)
    ] = 100,
    quick: Annotated[bool, typer.Option(help="small scenes only (a smoke run)")] = False,
    out: Annotated[Path, option("JSON results file", output_file)] = Path(
        "bench-results/bench.json"
    ),
    envs: Annotated[
        str,
        typer.Option(
            help="environments' speed (env and simulation steps/s, real-time factor at dt 0.01,"
            " 0.02, 0.03), written to envs.json beside the JSON: 'all', 'none', 'only' (skip"
            " the scenes) or comma-separated names"
        ),
    ] = "all",
    env_profile: Annotated[
        bool,
        typer.Option(
            help="with --envs, where each environment's step goes at dt 0.01 (shares of"
            " collision, forces, assembly, factorisation, solves, constraint rows and solve,"
            " the solver's other work, observation, reward, glue), written to env_profile.json"
        ),
    ] = False,
    profile: Annotated[
        bool,
        typer.Option(
            help="per SPEC scene, the default step's error against the exact one over 1 s and"
            " the time per step of each part (forces, assembly, factorisation, solves,"
            " constraints, the rest)"
        ),
    ] = True,
    batch: Annotated[
        str,
        typer.Option(help="batched stepping: comma-separated copy counts to time ('' skips)"),
    ] = "1,8,32",
    learner: Annotated[
        bool,
        typer.Option(
            help="the learner's cost per training step alone (SAC CartStemContact, PPO"
            " TrunkSpaceDebris: the thesis' networks on a stand-in task whose step is free),"
            " with its arithmetic against this machine's matrix-product speed; learner.json"
        ),
    ] = False,
    training: Annotated[
        bool,
        typer.Option(
            help="real training steps/s, updates included (SAC CartStemContact, PPO"
            " TrunkSpaceDebris, thesis configurations, a short window after the warm-up), with"
            " SB3's updates and with Pliant's, in turn; learner_training.json"
        ),
    ] = False,
    gradient: Annotated[
        bool,
        typer.Option(
            help="what a rollout gradient (pliant.diff) costs beside the rollout, on the coarse"
            " Finger and the Diamond; gradient.json"
        ),
    ] = False,
    element_pass: Annotated[
        bool,
        typer.Option(
            help="the polar corotational element pass one element at a time and vectorised"
            " across elements (ns per tet on one thread, Trunk, Diamond, 15 360-tet"
            " cantilever) against this machine's arithmetic and memory ceilings, and the"
            " default step with either; element_pass.json"
        ),
    ] = False,
    scenes: Annotated[
        bool,
        typer.Option(help="the SPEC scenes' speed (--no-scenes: only what the other flags ask)"),
    ] = True,
    goals: Annotated[
        bool,
        typer.Option(
            help="last, issue #62's goals (10x SOFA, 5x exact, 3x MuJoCo, 10x real time, 3x SAC"
            " training) met or missed, read from the bench.json, envs.json and"
            " learner_training.json beside --out; goals.json"
        ),
    ] = False,
) -> None:
    """Median steps/s beside SOFA's measured figures; writes JSON and a log-log plot."""
    from pliant.bench import run_benchmarks

    if scenes and envs != "only":
        run_benchmarks(
            meshes=meshes,
            repeats=repeats,
            steps=steps,
            quick=quick,
            out=out,
            console=console,
            profile=profile,
            batch=_copy_counts(batch),
        )
    if envs != "none":
        from pliant.bench.envs import report_envs

        names = None if envs in ("all", "only") else [n.strip() for n in envs.split(",")]
        report_envs(names, quick=quick, out=out.with_name("envs.json"), console=console)
        if env_profile:
            from pliant.bench.envs import report_env_profile

            out_profile = out.with_name("env_profile.json")
            report_env_profile(names, quick=quick, out=out_profile, console=console)
    if learner:
        from pliant.bench.learner import report_learner

        report_learner(quick=quick, out=out.with_name("learner.json"), console=console)
    if training:
        from pliant.bench.learner import report_training

        report_training(quick=quick, out=out.with_name("learner_training.json"), console=console)
    if element_pass:
        from pliant.bench.element_pass import report_element_pass

        report_element_pass(out=out.with_name("element_pass.json"), console=console, meshes=meshes)
    if gradient:
        from pliant.bench import report_gradient

        report_gradient(
            quick=quick, out=out.with_name("gradient.json"), console=console, repeats=repeats
        )
    if goals:
        from pliant.bench.goals import report_goals

        report_goals(out.parent, console=console)


def _copy_counts(text: str) -> tuple[int, ...]:
    """`--batch`: comma-separated copy counts (integers >= 1), or '' for none."""
    if not text.strip():
        return ()
    counts = numbers_list(text, "--batch")
    if any(c < 1 or c != int(c) for c in counts):
        raise typer.BadParameter(f"--batch: copy counts must be integers >= 1, got {text!r}")
    return tuple(int(c) for c in counts)
