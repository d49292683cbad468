"""``pliant train``, ``pliant eval``, ``pliant enjoy``, ``pliant export-policy``, ``pliant tune``:
reinforcement learning on Pliant's environments (docs/learning.md). Stable-Baselines3 and
PyTorch are imported when a command runs, not when the CLI starts."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console

from pliant.cli.support import assignments, json_or_text
from pliant.files import atomic_path, write_json
from pliant.threads import configure_threads

console = Console()

ALGO_HELP = "PPO, SAC, TD3, A2C, DQN or RecurrentPPO"


def _pairs(items: list[str] | None) -> dict:
    return {k: json_or_text(v) for k, v in assignments(items or []).items()}


def _quick_kwargs(env_id: str) -> dict:
    import pliant.envs as envs

    name = env_id.split("/")[-1].rsplit("-v", 1)[0]
    return dict(envs.ENVS[name].quick) if name in envs.ENVS else {}


def train(
    env: Annotated[str, typer.Argument(help="a Gymnasium id, e.g. pliant/CartStemContact-v0")],
    algo: Annotated[str, typer.Option(help=ALGO_HELP)] = "PPO",
    config: Annotated[
        Path | None, typer.Option(help="YAML: TrainConfig fields, SB3 ones under hyperparams")
    ] = None,
    out: Annotated[
        Path | None, typer.Option(help="run folder (default runs/ENV_ALGO_sSEED)")
    ] = None,
    steps: Annotated[int | None, typer.Option(help="total environment steps")] = None,
    n_envs: Annotated[int | None, typer.Option(help="parallel environments")] = None,
    seed: Annotated[int | None, typer.Option()] = None,
    env_kwarg: Annotated[
        list[str] | None, typer.Option(help="KEY=VALUE environment argument (repeatable)")
    ] = None,
    hyper: Annotated[
        list[str] | None, typer.Option(help="KEY=VALUE SB3 argument (repeatable)")
    ] = None,
    quick: Annotated[bool, typer.Option(help="the environment's fast test variant")] = False,
    normalize: Annotated[bool | None, typer.Option(help="VecNormalize")] = None,
    eval_freq: Annotated[int | None, typer.Option()] = None,
    eval_episodes: Annotated[int | None, typer.Option()] = None,
    checkpoint_freq: Annotated[int | None, typer.Option()] = None,
    video_episodes: Annotated[int | None, typer.Option(help="episodes in eval.gif")] = None,
    vec_env: Annotated[str | None, typer.Option(help="subproc, dummy or ray")] = None,
    ray: Annotated[
        str | None, typer.Option(help="environments as Ray actors: 'auto', 'local' or an address")
    ] = None,
    bc_expert: Annotated[
        str | None, typer.Option(help="MODULE:FUNCTION expert for behaviour cloning")
    ] = None,
    bc_epochs: Annotated[int, typer.Option(help="behaviour-cloning epochs")] = 100,
    bc_episodes: Annotated[int, typer.Option(help="expert episodes for cloning")] = 20,
    resume: Annotated[bool, typer.Option(help="continue the run in --out")] = False,
    device: Annotated[str | None, typer.Option(help="cpu, cuda or auto")] = None,
    progress: Annotated[bool, typer.Option(help="rich progress bar")] = True,
    torch_threads: Annotated[
        int | None,
        typer.Option(
            min=1,
            help="PyTorch threads of the learner (default PyTorch's, one per core); 1 on a"
            " machine the run shares, where a second one adds CPU time and no speed",
        ),
    ] = None,
) -> None:
    """Train ALGO on ENV; checkpoints, evaluations, TensorBoard logs and a GIF in --out."""
    from pliant.learn.config import load_config

    if torch_threads is not None:
        configure_threads(torch_threads=torch_threads)
    from pliant.learn.training import train as run_training

    overrides = {
        "total_timesteps": steps,
        "n_envs": n_envs,
        "seed": seed,
        "normalize": normalize,
        "eval_freq": eval_freq,
        "eval_episodes": eval_episodes,
        "checkpoint_freq": checkpoint_freq,
        "video_episodes": video_episodes,
        "vec_env": "ray" if ray else vec_env,
        "ray_address": ray,
        "device": device,
    }
    env_kwargs = {**(_quick_kwargs(env) if quick else {}), **_pairs(env_kwarg)}
    if env_kwargs:
        overrides["env_kwargs"] = env_kwargs
    if hyper:
        overrides["hyperparams"] = _pairs(hyper)
    if bc_expert:
        overrides["bc"] = {"expert": bc_expert, "epochs": bc_epochs, "episodes": bc_episodes}
    try:
        cfg = load_config(env, algo, config, overrides)
    except (ValueError, FileNotFoundError) as exc:
        raise typer.BadParameter(str(exc)) from exc
    run_dir = out or Path("runs") / f"{cfg.env_name}_{algo}_s{cfg.seed}"
    console.print(f"{algo} on {env}: {cfg.total_timesteps} steps, {cfg.n_envs} env(s) -> {run_dir}")
    result = run_training(
        None if resume else cfg,
        run_dir,
        resume=resume,
        progress_bar=progress,
        total_timesteps=steps if resume else None,
    )
    console.print_json(json.dumps(result.summary))


def _evaluate(model, env, episodes, env_kwarg, algo, seed, **options):
    """:func:`pliant.learn.evaluate.evaluate_saved` of a command's arguments."""
    from pliant.learn.evaluate import evaluate_saved

    return evaluate_saved(
        model, env, episodes=episodes, env_kwargs=_pairs(env_kwarg), algo=algo, seed=seed, **options
    )


def eval_(
    model: Annotated[
        Path, typer.Argument(help="model.zip, its folder, a run folder, or a kept policy.npz")
    ],
    env: Annotated[str | None, typer.Argument(help="default: the one it was trained on")] = None,
    episodes: Annotated[int, typer.Option()] = 10,
    algo: Annotated[str | None, typer.Option(help="if the model has no meta.json")] = None,
    env_kwarg: Annotated[list[str] | None, typer.Option(help="KEY=VALUE (repeatable)")] = None,
    seed: Annotated[int, typer.Option(help="episode k is reset with seed + k")] = 10_000,
    stochastic: Annotated[bool, typer.Option(help="sample actions")] = False,
    json_out: Annotated[Path | None, typer.Option("--json", help="write the result")] = None,
) -> None:
    """Evaluate a trained policy: success rate, mean return (JSON)."""
    result = _evaluate(model, env, episodes, env_kwarg, algo, seed, deterministic=not stochastic)
    text = json.dumps(result.to_dict(per_episode=True), indent=1)
    if json_out:
        with atomic_path(json_out) as tmp:
            tmp.write_text(text)
    console.print_json(json.dumps(result.to_dict()))


def enjoy(
    model: Annotated[Path, typer.Argument(help="model.zip, its folder, or a run folder")],
    env: Annotated[str | None, typer.Argument(help="default: the one it was trained on")] = None,
    episodes: Annotated[int, typer.Option()] = 1,
    algo: Annotated[str | None, typer.Option()] = None,
    env_kwarg: Annotated[list[str] | None, typer.Option(help="KEY=VALUE (repeatable)")] = None,
    seed: Annotated[int, typer.Option()] = 10_000,
    gif: Annotated[Path, typer.Option(help="output GIF")] = Path("enjoy.gif"),
) -> None:
    """Run a trained policy and save its episodes as a GIF."""
    result = _evaluate(model, env, episodes, env_kwarg, algo, seed, gif=gif, gif_episodes=episodes)
    console.print(f"{gif}: {episodes} episode(s), mean return {result.mean_return:.4g}")


def export_policy(
    model: Annotated[Path, typer.Argument(help="a run folder, its final/ or best/, a model.zip")],
    out: Annotated[Path, typer.Argument(help="the kept policy (.npz)")],
) -> None:
    """Keep what acting needs of a trained policy in one small file (pliant.learn.kept): the
    actor's float32 weights, the observation normaliser, the spaces and where it comes from.
    `pliant eval OUT` evaluates it."""
    from pliant.learn.evaluate import export_run

    written = export_run(model, out)
    console.print(f"{written}: {written.stat().st_size / 1e6:.2f} MB (from {model})")


def tune(
    env: Annotated[str, typer.Argument(help="a Gymnasium id")],
    config: Annotated[Path, typer.Option(help="sweep YAML (pliant.learn.distributed)")],
    algo: Annotated[str | None, typer.Option(help="overrides the sweep's algo")] = None,
    out: Annotated[Path, typer.Option(help="folder of the trials' runs")] = Path("runs/tune"),
    ray: Annotated[str | None, typer.Option(help="cluster address (default: local)")] = None,
    num_samples: Annotated[int | None, typer.Option()] = None,
    cpus_per_trial: Annotated[float, typer.Option()] = 1.0,
) -> None:
    """A Ray Tune sweep of training runs (seeds, hyper-parameters)."""
    from pliant.learn.distributed import tune_sweep

    rows = tune_sweep(
        env,
        config,
        algo=algo,
        out=out,
        address=ray,
        num_samples=num_samples,
        cpus_per_trial=cpus_per_trial,
    )
    write_json(Path(out) / "sweep_results.json", rows, default=str)
    console.print_json(json.dumps(rows, default=str))
