"""``pliant plan``: play an episode of a Gymnasium environment with OPD or UCT; save the actions,
a report of rewards and costs, and a GIF of the real trajectory."""

from __future__ import annotations

import importlib
from pathlib import Path
from typing import Annotated, Any

import numpy as np
import typer
from rich.console import Console
from rich.markup import escape

from pliant.cli.support import assignments, json_or_text
from pliant.errors import PlanningError, PliantError
from pliant.files import write_json
from pliant.planning.opd import OPD
from pliant.planning.planner import Planner
from pliant.planning.run import run_episode
from pliant.planning.uct import UCT

console = Console()
# One line per error, never wrapped, so scripts can read it.
errors = Console(stderr=True, soft_wrap=True)


def plan(
    env_id: Annotated[
        str,
        typer.Argument(
            metavar="ENV",
            help="a Gymnasium id: pliant/Diamond-v0, CartPole-v1, module:Id (imports module)",
        ),
    ],
    algo: Annotated[str, typer.Option(help="opd or uct")] = "opd",
    budget: Annotated[int, typer.Option(help="simulated environment steps per decision")] = 200,
    gamma: Annotated[float, typer.Option(help="discount factor in (0, 1]")] = 0.9,
    depth: Annotated[
        int | None,
        typer.Option(help="OPD: maximum depth (default none); UCT: horizon (default 20)"),
    ] = None,
    steps: Annotated[int, typer.Option(help="decisions played on the real environment")] = 50,
    out: Annotated[Path, typer.Option(help="output folder")] = Path("out/plan"),
    seed: Annotated[int, typer.Option(help="seed of the reset and of UCT's rollouts")] = 0,
    reuse_tree: Annotated[
        bool,
        typer.Option(help="keep the played child's subtree (no: rebuild each step, Table 3.1)"),
    ] = True,
    env_kwarg: Annotated[
        list[str] | None,
        typer.Option(
            "--env-kwarg",
            "-k",
            help="KEY=VALUE for gymnasium.make, e.g. action_type=discrete (VALUE read as JSON,"
            " else text); repeatable",
        ),
    ] = None,
) -> None:
    """Plan each decision of an episode of ENV by tree search (OPD or UCT) over saved states."""
    try:
        if steps < 1:
            raise PlanningError(f"--steps must be >= 1, got {steps}")
        planner = _planner(algo, budget, gamma, depth, seed, reuse_tree)
        env = _make(env_id, _kwargs(env_kwarg or []))
    except (PlanningError, typer.BadParameter) as exc:
        raise _usage_error(exc) from None

    frames = _Frames()
    try:
        with console.status(f"{algo.upper()} on {env_id}: {steps} decisions at most"):
            report = run_episode(env, planner, max_steps=steps, seed=seed, on_step=frames.keep)
    except PlanningError as exc:  # the environment does not suit the planner
        raise _usage_error(exc) from None
    except PliantError as exc:  # the simulation failed
        errors.print(f"[red]error:[/red] {escape(str(exc))}")
        raise typer.Exit(1) from None
    finally:
        env.close()

    out.mkdir(parents=True, exist_ok=True)
    gif = None
    if frames.images:
        from pliant.viz import save_gif

        fps = env.metadata.get("render_fps", 10)
        gif = save_gif(frames.images, out / "trajectory.gif", fps=fps)
    summary = {
        "env": env_id,
        "algo": algo,
        "budget": budget,
        "gamma": gamma,
        "depth": depth,
        "seed": seed,
        "reuse_tree": reuse_tree,
        "discounted_return": report.discounted_return(gamma),
        **report.to_dict(),
        "gif": gif.name if gif else None,
    }
    write_json(out / "actions.json", report.actions, indent=None)
    write_json(out / "report.json", summary)
    end = "terminated" if report.terminated else "truncated" if report.truncated else "stopped"
    console.print(
        f"{env_id}, {algo.upper()}: total reward {report.total_reward:.4g} in"
        f" {len(report.actions)} steps ({end}); planning {summary['planning_time']:.3g} s,"
        f" {summary['expansions']} expansions, {summary['simulated_steps']} simulated steps"
    )
    saved = ", ".join(str(out / name) for name in ("actions.json", "report.json"))
    console.print(f"saved {saved}" + (f", {gif}" if gif else f" (no GIF: {frames.failure})"))


class _Frames:
    """The real trajectory's images, for as long as the environment draws RGB arrays."""

    def __init__(self) -> None:
        self.images: list[np.ndarray] = []
        self.failure: str | None = None

    def keep(self, env: Any) -> None:
        if self.failure is not None:
            return
        if env.render_mode != "rgb_array":
            self.failure = "the environment draws no RGB frames"
            return
        import gymnasium

        try:
            frame = env.render()
        except gymnasium.error.Error as exc:  # e.g. a missing drawing library: plan anyway
            self.failure = " ".join(str(exc).split())
            return
        if isinstance(frame, np.ndarray) and frame.ndim == 3:
            self.images.append(frame)
        else:
            self.failure = "the environment draws no RGB frames"


def _planner(
    algo: str, budget: int, gamma: float, depth: int | None, seed: int, reuse_tree: bool
) -> Planner:
    if algo == "opd":
        return OPD(budget=budget, gamma=gamma, max_depth=depth, reuse_tree=reuse_tree)
    if algo == "uct":
        horizon = {} if depth is None else {"horizon": depth}
        return UCT(budget=budget, gamma=gamma, seed=seed, reuse_tree=reuse_tree, **horizon)
    raise PlanningError(f"--algo must be 'opd' or 'uct', got {algo!r}")


def _kwargs(items: list[str]) -> dict[str, Any]:
    return {k: json_or_text(v) for k, v in assignments(items, option="--env-kwarg").items()}


def _make(env_id: str, kwargs: dict[str, Any]) -> Any:
    """``gymnasium.make``, asking for RGB frames where the environment draws them; Pliant's own
    ids register on importing ``pliant.envs``."""
    try:
        import gymnasium
    except ImportError:
        raise PlanningError("planning needs gymnasium: pip install 'pliant[learn]'") from None
    if env_id.startswith("pliant/"):
        try:
            import pliant.envs  # noqa: F401  (registers the pliant/ ids)
        except ImportError:
            raise PlanningError(f"{env_id}: this installation has no pliant.envs") from None
    module, _, name = env_id.rpartition(":")  # gymnasium's "module:Id": the module registers Id
    try:
        if module:
            importlib.import_module(module)
        spec = gymnasium.spec(name)
        creator = spec.entry_point
        if isinstance(creator, str):
            creator = gymnasium.envs.registration.load_env_creator(creator)
        if "rgb_array" in getattr(creator, "metadata", {}).get("render_modes", ()):
            kwargs = {"render_mode": "rgb_array", **kwargs}
        return gymnasium.make(name, **kwargs)
    except (gymnasium.error.Error, ModuleNotFoundError, TypeError) as exc:
        # unknown id or module, or keyword arguments the environment does not take
        raise PlanningError(f"cannot make {env_id!r}: {exc}") from None


def _usage_error(exc: Exception) -> typer.Exit:
    message = exc.message if isinstance(exc, typer.BadParameter) else str(exc)
    errors.print(f"[red]error:[/red] {escape(' '.join(message.split()))}")
    return typer.Exit(2)
