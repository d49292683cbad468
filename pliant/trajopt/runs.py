"""Trajectory-optimisation runs end to end, as ``pliant trajopt`` gives them: the Stiff-Flop's and
the Lianford's scenarios by box-DDP on the full FEM (:func:`run_scenario`), the two-goal task by
MPC with a learned condensed model (:func:`run_learned_mpc`), and the report of a solve
(:func:`summary`): a table, plots, GIFs and a JSON report each."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from rich.console import Console
from rich.table import Table

from pliant.files import write_json

console = Console()
BACKENDS = ("numpy", "crocoddyl")


def summary(name: str, result, scenario) -> dict:
    """The JSON report of one solve: convergence and how close the effector came."""
    goals, xs, n = scenario.goals, result.xs, scenario.cost.horizon
    half = n // 2
    m = goals.shape[1]
    return {
        "run": name,
        **result.report(),
        "error_first_goal_at_switch": float(np.linalg.norm(xs[half, :m] - goals[half])),
        "error_final_goal_at_end": float(np.linalg.norm(xs[n, :m] - goals[n])),
        "rms_tracking_error": float(np.sqrt(np.mean(np.sum((xs[:, :m] - goals) ** 2, axis=1)))),
    }


# The thesis' figures for the scenarios below (§5.2.4-5.2.5): Fig. 5.21 and 5.22 show the
# trajectories; the thesis gives no iteration count for them (only the Diamond's 208).
_PLOTS = {
    "stiff-flop": (("stiff-flop-middle", "stiff-flop-tip"), ("mm", "mm/s", "bar"), 0.01),
    "lianford-spiral": (("lianford-spiral",), ("mm", "mm/s", "mN mm"), 1.0),
    "lianford-pick-place": (("lianford-pick-place",), ("mm", "mm/s", "mN mm"), 1.0),
    "lianford-orientation": (("lianford-orientation",), ("mm", "mm/s", "mN mm"), 1.0),
}
_QUICK = {"stiff-flop": 4, "lianford-spiral": 10, "lianford-pick-place": 9}


def scenario_report(name: str, result, scenario) -> dict:
    """Convergence and distances to the goals (nodes without a goal left out): at the end, RMS
    over the nodes, largest."""
    goals = scenario.goals
    m = goals.shape[1]
    gap = np.where(np.isfinite(goals), result.xs[:, :m] - np.nan_to_num(goals), 0.0)
    scored = np.any(np.isfinite(goals), axis=1)
    errors = np.linalg.norm(gap, axis=1)[scored]
    orientation = {}
    points = goals[-1].reshape(-1, 3)
    held = np.flatnonzero(np.all(np.isfinite(points), axis=1))
    if held.size == 2:  # two effectors with goals: the angle of the line through them
        reached = result.xs[-1, :m].reshape(-1, 3)[held]
        start = result.xs[0, :m].reshape(-1, 3)[held]
        lines = [p[0] - p[1] for p in (points[held], reached, start)]

        def angle(a, b):
            c = a @ b / (np.linalg.norm(a) * np.linalg.norm(b))
            return float(np.degrees(np.arccos(np.clip(c, -1.0, 1.0))))

        orientation = {
            "final_orientation_error_deg": angle(lines[0], lines[1]),
            "goal_rotation_deg": angle(lines[0], lines[2]),
        }
    return {
        "run": name,
        **result.report(),
        **orientation,
        "final_error": float(errors[-1]),
        "rms_tracking_error": float(np.sqrt(np.mean(errors**2))),
        "max_tracking_error": float(errors.max()),
        "goal_span": float(np.nanmax(np.ptp(goals, axis=0))) if goals.shape[0] > 1 else 0.0,
        "actuation_range": [float(result.us.min()), float(result.us.max())],
        "bounds": [scenario.bounds.lower.tolist(), scenario.bounds.upper.tolist()],
    }


def run_scenario(
    command: str,
    *,
    quick: bool = False,
    horizon: int | None = None,
    max_iterations: int = 100,
    tolerance: float = 1e-4,
    frames: int = 20,
    out: Path = Path("out/trajopt"),
) -> dict:
    """Solve each run of a scenario command with box-DDP on the full FEM; write
    `{command}.png` (positions, velocities, actuation with bounds), a GIF per run and
    `{command}.json`. --quick: a short horizon, 2 iterations, 3 frames (for tests)."""
    from pliant.trajopt.ddp import BoxDDP
    from pliant.trajopt.plots import plot_trajectory
    from pliant.trajopt.scenarios import SCENARIOS

    names, units, scale = _PLOTS[command]
    if quick:
        horizon = horizon or _QUICK.get(command, 6)
        max_iterations, frames = min(max_iterations, 2), min(frames, 3)
    solver = BoxDDP(max_iterations=max_iterations, tolerance=tolerance)
    reports, runs, goals, scenarios = [], {}, {}, {}
    for name in names:
        scenario = SCENARIOS[name](**({"horizon": horizon} if horizon else {}))
        with console.status(f"{name}: box-DDP on the full FEM"):
            result = solver.solve(scenario.dynamics, scenario.start, scenario.cost, scenario.bounds)
        reports.append(scenario_report(name, result, scenario))
        runs[name] = (result.xs, scale * result.us)
        goals[name] = scenario.goals
        scenarios[name] = (scenario, result)
    table = Table(title=f"{command}: box-DDP on condensed FEM dynamics")
    for col in ("run", "iterations", "cost", "wall (s)", "final error", "RMS error", "bounds ok"):
        table.add_column(col)
    for r in reports:
        table.add_row(
            r["run"],
            str(r["iterations"]),
            f"{r['cost']:.4g}",
            f"{r['wall_time_s']:.1f}",
            f"{r['final_error']:.3f}",
            f"{r['rms_tracking_error']:.3f}",
            str(r["bound_violation"] == 0.0),
        )
    console.print(table)
    out.mkdir(parents=True, exist_ok=True)
    scenario = scenarios[names[0]][0]
    dt = scenario.dynamics.dt
    written = [
        plot_trajectory(
            np.arange(scenario.cost.horizon + 1) * dt,
            runs,
            goals,
            (scale * scenario.bounds.lower, scale * scenario.bounds.upper),
            out / f"{command}.png",
            title=f"{command}: box-DDP, full-FEM forward pass",
            units=units,
            relative=True,
        )
    ]
    if frames > 0:
        from pliant.robots import entry
        from pliant.viz import save_gif
        from pliant.viz.model_view import RobotCamera

        for name, (scenario, result) in scenarios.items():
            camera = RobotCamera(scenario.model, view=entry(scenario.model.name).view)
            states = result.rollout.states
            picks = np.unique(np.linspace(0, len(states) - 1, frames).round().astype(int))
            m = scenario.goals.shape[1]
            images = []
            for k in picks:
                shown = scenario.goals[k].reshape(m // 3, 3)
                shown = shown[np.all(np.isfinite(shown), axis=1)]
                images.append(
                    camera.frame(states[k], goals=shown, title=f"{name}  t = {k * dt:.2f} s")
                )
            written.append(save_gif(images, out / f"{name}.gif", fps=8))
    report = {"scenario": command, "quick": quick, "runs": reports}
    path = out / f"{command}.json"
    write_json(path, report)
    written.append(path)
    console.print("saved " + ", ".join(str(p) for p in written))
    return report


# Learned condensed models the learned MPC commands use, and how a missing one is made:
# a short collection around the task's actuator distances and a small network.
LEARNED_MODELS = Path("experiments/results/trajopt/learned")
_ROBOT_KWARGS = {"diamond": {"mesh_size": 20.0}, "finger": {"resolution": "coarse"}}


def distance_box(model, states) -> list[tuple[float, float]]:
    """Bounds of each actuator distance over `states` (a trajectory of the task), widened by
    20 % of their span and 0.5 mm: the region a model for the task must cover."""
    d = np.array([model.actuator_distances(s.positions) for s in states])
    low, high = d.min(axis=0), d.max(axis=0)
    pad = 0.2 * (high - low) + 0.5
    return [(float(lo), float(hi)) for lo, hi in zip(low - pad, high + pad, strict=True)]


def learned_model(robot: str, path: Path, box, *, samples: int, epochs: int):
    """The learned condensed model at `path`, or, if there is none, one collected (`samples`
    Halton samples of the actuator distances in `box`, one worker) and trained (3 x 128,
    `epochs` epochs) there now, as `pliant condensed collect` and `train` would."""
    from pliant.condensed.collect import load_or_collect
    from pliant.condensed.dataset import CollectionPlan
    from pliant.condensed.learned import LearnedCondensedModel
    from pliant.condensed.train import TrainConfig, evaluate, train_condensed

    if path.is_file():
        return LearnedCondensedModel.load(path), False
    console.print(
        f"no learned model at {path}: collecting {samples} samples and training {epochs} epochs"
    )
    plan = CollectionPlan(robot, tuple(box), samples, robot_kwargs=_ROBOT_KWARGS[robot])
    dataset = load_or_collect(plan, path.with_suffix(".h5"), workers=1)
    config = TrainConfig(
        epochs=epochs, batch_size=16, learning_rate=1e-3, hidden=(128, 128, 128), progress=False
    )
    learned, _ = train_condensed(dataset, config)
    learned.training["test"] = evaluate(learned, dataset.test)
    learned.save(path)
    return learned, True


def run_learned_mpc(
    robot: str,
    *,
    model: Path | None = None,
    horizon: int = 20,
    iterations: int = 3,
    steps: int = 100,
    samples: int = 300,
    epochs: int = 1000,
    out: Path = Path("out/trajopt"),
) -> dict:
    """The two-goal task of `robot` three ways, each closed on (or run on) the full FEM: the
    full-FEM DDP (offline), the MPC on the condensed dynamics frozen at each FEM state, and the
    MPC whose prediction is the learned condensed model; `{robot}_mpc_learned.{json,png}`."""
    import time

    from pliant.trajopt.ddp import BoxDDP
    from pliant.trajopt.learned import LearnedMPC
    from pliant.trajopt.mpc import CondensedMPC
    from pliant.trajopt.plots import plot_trajectory
    from pliant.trajopt.scenarios import SCENARIOS

    # A model given by name is read (and checked) before the minutes of the DDP below.
    given = None
    if model is not None and model.is_file():
        from pliant.condensed.learned import LearnedCondensedModel

        given = LearnedCondensedModel.load(model)
    scenario = SCENARIOS[robot](horizon=steps)
    goals, m = scenario.goals, scenario.goals.shape[1]
    runs, reports = {}, {}
    with console.status(f"{robot}: full-FEM DDP"):
        ddp = BoxDDP(max_iterations=100, tolerance=1e-4).solve(
            scenario.dynamics, scenario.start, scenario.cost, scenario.bounds
        )
    runs["full-FEM DDP"] = (ddp.xs, ddp.us)
    reports["full-FEM DDP"] = {
        "iterations": ddp.iterations,
        "wall_time_s": ddp.wall_time,
        "rollouts": ddp.rollouts,
    }
    path = model or LEARNED_MODELS / f"{robot}.pt"
    box = distance_box(scenario.model, ddp.rollout.states)
    if given is not None:
        learned, trained = given, False
    else:
        learned, trained = learned_model(robot, path, box, samples=samples, epochs=epochs)
    controllers = {
        f"MPC, frozen FEM condensed (H = {horizon})": CondensedMPC,
        f"MPC, learned prediction (H = {horizon})": lambda dyn, *a, **k: LearnedMPC(
            dyn, learned, *a, **k
        ),
    }
    for name, make in controllers.items():
        mpc = make(
            scenario.dynamics,
            scenario.cost,
            scenario.bounds,
            horizon=horizon,
            max_iterations=iterations,
        )
        clock = time.perf_counter()
        with console.status(f"{robot}: {name}"):
            result = mpc.run(scenario.start)
        runs[name] = (result.xs, result.us)
        reports[name] = {**result.report(), "wall_time_s": time.perf_counter() - clock}
        if isinstance(mpc, LearnedMPC):
            reports[name]["largest_extrapolation_mm"] = mpc.extrapolation
    for name, (xs, us) in runs.items():
        errors = np.linalg.norm(xs[:, :m] - goals, axis=1)
        reports[name].update(
            {
                "cost": scenario.cost.value(xs, us),
                "rms_to_goals_mm": float(np.sqrt(np.mean(errors**2))),
                "end_error_mm": float(errors[-1]),
                "rms_to_ddp_mm": float(
                    np.sqrt(np.mean(np.sum((xs[:, :m] - ddp.xs[:, :m]) ** 2, axis=1)))
                ),
                "bound_violation": scenario.bounds.violation(us),
            }
        )
    table = Table(title=f"{robot}: two goals, MPC with the learned condensed model")
    for col in ("run", "loop (Hz)", "with FEM (Hz)", "RMS goals", "RMS to DDP", "end", "wall"):
        table.add_column(col)
    for name, r in reports.items():
        table.add_row(
            name,
            f"{r['loop_rate_hz']:.0f}" if "loop_rate_hz" in r else "-",
            f"{r['closed_loop_rate_hz']:.0f}" if "closed_loop_rate_hz" in r else "-",
            f"{r['rms_to_goals_mm']:.2f}",
            f"{r['rms_to_ddp_mm']:.2f}",
            f"{r['end_error_mm']:.3f}",
            f"{r['wall_time_s']:.1f}",
        )
    console.print(table)
    out.mkdir(parents=True, exist_ok=True)
    dt = scenario.dynamics.dt
    plot = plot_trajectory(
        np.arange(steps + 1) * dt,
        runs,
        goals,
        (scenario.bounds.lower, scenario.bounds.upper),
        out / f"{robot}_mpc_learned.png",
        title=f"{robot}: full-FEM DDP, MPC frozen condensed, MPC learned (closed on the FEM)",
        relative=True,
    )
    report = {
        "scenario": f"{robot}-mpc-learned",
        "horizon": horizon,
        "iterations_per_step": iterations,
        "steps": steps,
        "dt": dt,
        "learned_model": {
            "path": str(path),
            "trained_now": trained,
            "samples": learned.plan.n_train,
            "box": [learned.input_box.low.tolist(), learned.input_box.high.tolist()],
            "hidden": list(learned.network.hidden),
            **learned.training,
        },
        "runs": reports,
    }
    path_json = out / f"{robot}_mpc_learned.json"
    write_json(path_json, report)
    console.print(f"saved {plot}, {path_json}")
    return report
