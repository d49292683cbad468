"""``pliant proxy calibrate ROBOT``: fit a beam-skeleton proxy to its FEM robot (thesis
§4.1.1); a JSON report of the parameters and errors, the study in SQLite (resumable)."""

from __future__ import annotations

import json
from dataclasses import replace
from functools import partial
from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console

from pliant.cli.options import OutFolder, option
from pliant.cli.support import (
    at_least_one,
    command_group,
    fraction,
    non_negative,
    numbers_list,
    one_of,
)
from pliant.files import write_json, write_results

app = command_group("Beam-skeleton proxies of FEM robots (thesis §4.1).")
console = Console()


@app.command()
def calibrate(
    robot: Annotated[
        str,
        typer.Argument(
            help="multigait (its hand gait), multigait-patterns (16 actions, validated on the"
            " hand gait), multigait-joint (both in one trajectory), trunk, or trunk-cube (the"
            " cube's mass, a posteriori)",
            callback=one_of(
                "multigait", "multigait-patterns", "multigait-joint", "trunk", "trunk-cube"
            ),
        ),
    ],
    trials: Annotated[int, option("trials the study is to hold", at_least_one)] = 40,
    safety: Annotated[
        float, option("factor in (0, 1] on the calibrated max curvatures", fraction)
    ] = 0.9,
    seed: Annotated[int, typer.Option(help="TPE sampler seed")] = 0,
    reference: Annotated[
        Path | None, typer.Option(help="a saved FEM trajectory (.npz); made and saved if absent")
    ] = None,
    mass_tolerance: Annotated[
        float | None,
        option(
            "keep the proxy's mass within this fraction of the FEM robot's (a constraint"
            " of the search; a study of its own, ROBOT-mass)",
            fraction,
        ),
    ] = None,
    travel_weight: Annotated[
        float,
        option(
            "add this weight times the travel error (mm: the matched points' centroid"
            " moved over each action, FEM vs proxy) to the loss (Multigait)",
            non_negative,
        ),
    ] = 0.0,
    travel_actions: Annotated[
        int,
        typer.Option(
            help="measure the travel over this many actions at a time (a gait cycle's worth"
            " weighs a gait's drift rather than each action's move; a study of its own)",
            min=1,
        ),
    ] = 1,
    friction: Annotated[
        str | None,
        typer.Option(
            help="LOW,HIGH: also fit the proxy's floor friction in this box (Multigait)",
        ),
    ] = None,
    cross_stiffness: Annotated[
        str | None,
        typer.Option(
            help="LOW,HIGH (kPa): also fit the Multigait proxy's four cross beams' stiffness,"
            " which otherwise is the centre's (a study of its own, -cross)",
        ),
    ] = None,
    contraction: Annotated[
        str | None,
        typer.Option(
            help="LOW,HIGH: also fit each Trunk beam's axial shortening per unit bending in"
            " this box (the FEM Trunk shortens as its cables bend it; a study of its own)",
        ),
    ] = None,
    neutral: Annotated[
        str,
        option(
            "the layer the Multigait proxy's chambers bend its beams about: axis (the"
            " thesis' inextensible beams) or underside (the strain-limiting layer, which keeps"
            " its length: the beams stretch as they curl; a study of its own, -underside)",
            one_of("axis", "underside"),
        ),
    ] = "axis",
    contact: Annotated[
        str,
        option(
            "how the proxy touches the floor and the cube: nodes (balls at its nodes) or"
            " surface (the FEM's colliding points skinned onto it)",
            one_of("nodes", "surface"),
        ),
    ] = "nodes",
    start: Annotated[
        Path | None,
        typer.Option(
            help="a calibration report (JSON) whose parameters the study tries first",
            exists=True,
            dir_okay=False,
        ),
    ] = None,
    out: OutFolder = Path("out/proxy"),
) -> None:
    """Calibrate ROBOT's proxy on its FEM model: Optuna TPE, study resumed from
    OUT/ROBOT.db, report in OUT/ROBOT_calibration.json.

    The study is named after what it fits: ROBOT, with -mass, -travel{W}[x{K}], -friction,
    -contraction, -cross, -underside and -surface for the options that change the search."""
    from pliant.proxy.calibrate import calibrate as fit
    from pliant.proxy.calibrate import travel, travel_error
    from pliant.proxy.references import Reference, setup

    robot_setup = setup(robot)
    if travel_actions > 1 and travel_weight == 0.0:
        raise typer.BadParameter("--travel-actions: there is no travel term (--travel-weight 0)")
    if travel_weight > 0.0 and robot_setup.action_duration is None:
        raise typer.BadParameter(
            f"--travel-weight: {robot}'s reference is not a sequence of actions to measure the"
            " travel over"
        )
    space = dict(robot_setup.space)
    if friction is not None:
        if not robot.startswith("multigait"):
            raise typer.BadParameter("--friction: only the Multigait proxy's friction is fitted")
        space["friction"] = _box(friction, "--friction")
    if cross_stiffness is not None:
        if not robot.startswith("multigait"):
            raise typer.BadParameter("--cross-stiffness: only the Multigait proxy has cross beams")
        space["cross_stiffness"] = _box(cross_stiffness, "--cross-stiffness", positive=True)
    if contraction is not None:
        if robot != "trunk":
            raise typer.BadParameter("--contraction: only the Trunk proxy's beams contract")
        box = _box(contraction, "--contraction", below=1.0)
        space["lower_contraction"] = space["upper_contraction"] = box
    if neutral != "axis" and not robot.startswith("multigait"):
        raise typer.BadParameter("--neutral: only the Multigait's chambers bend a layer")
    builder = {"neutral": neutral} if neutral != "axis" else {}
    builder |= {"contact": contact} if contact != "nodes" else {}
    if builder:
        robot_setup = replace(robot_setup, build=partial(robot_setup.build, **builder))
    initial = None if start is None else _fitted_parameters(start)
    out.mkdir(parents=True, exist_ok=True)
    path = reference if reference is not None else out / f"{robot}_reference.npz"

    def load_or_simulate(path: Path, simulate) -> Reference:
        if path.exists():
            return Reference.load(path)
        console.print(f"simulating the FEM for the reference trajectory {path.name}")
        data = simulate()
        data.save(path)
        return data

    data = load_or_simulate(path, robot_setup.reference)
    if mass_tolerance is not None and robot == "trunk-cube":
        raise typer.BadParameter("--mass-tolerance: the cube's calibration fits its mass alone")
    if mass_tolerance is not None and not data.mass > 0.0:
        raise typer.BadParameter(
            f"--mass-tolerance: {path} holds no FEM mass (saved before it was kept): delete it"
            " to simulate it again"
        )
    interval = (
        None
        if robot_setup.action_duration is None
        else max(1, round(robot_setup.action_duration / data.dt)) * travel_actions
    )
    if travel_actions > 1 and interval is not None and interval > len(data.points):
        raise typer.BadParameter(
            f"--travel-actions: {travel_actions} actions are longer than the reference {path}"
        )
    study = robot + ("" if mass_tolerance is None else "-mass")
    study += (
        (f"-travel{travel_weight:g}" if travel_weight > 0.0 else "")
        + (f"x{travel_actions}" if travel_actions > 1 else "")
        + ("-friction" if friction is not None else "")
        + ("-contraction" if contraction is not None else "")
        + ("-cross" if cross_stiffness is not None else "")
    )
    study += ("" if neutral == "axis" else f"-{neutral}") + (
        "" if contact == "nodes" else f"-{contact}"
    )
    result = fit(
        robot_setup.simulate(data),
        data.points,
        space,
        trials=trials,
        storage=f"sqlite:///{out / f'{robot}.db'}",
        study_name=study,
        seed=seed,
        safety=safety,
        mass=robot_setup.mass if robot != "trunk-cube" else None,
        target_mass=data.mass,
        mass_tolerance=mass_tolerance,
        travel_weight=travel_weight,
        travel_interval=interval,
        start=initial,
    )
    report = {
        "robot": robot,
        "trials": result.trials,
        "optimisation_error_mm": result.optimisation_error,
        "validation_error_mm": result.validation_error,
        "parameters": result.parameters,
        "proxy_parameters": result.proxy_parameters,
        "safety": safety,
        "reference": str(path),
        "proxy_mass_kg": result.mass,
        "fem_mass_kg": data.mass if data.mass > 0.0 else None,
        "mass_tolerance": mass_tolerance,
        "feasible_trials": result.feasible_trials,
        "study": study,
        "contact": contact,
        "neutral": neutral,
    }
    if interval is not None and len(data.points) >= interval:  # each action's move, both
        best = robot_setup.simulate(data)(result.parameters)
        report["travel"] = {
            "weight": travel_weight,
            "interval_steps": interval,
            "actions": travel_actions,
            "error_mm": travel_error(data.points, best, interval),
            "loss": result.loss,
            "fem_mm": travel(data.points, interval).round(3).tolist(),
            "proxy_mm": travel(best, interval).round(3).tolist(),
        }
    if robot_setup.other is not None:  # validation on other actions than the fitted ones
        from pliant.proxy.calibrate import mean_distance

        name, simulate = robot_setup.other
        other = load_or_simulate(out / f"{name}_reference.npz", simulate)
        points = robot_setup.simulate(other)(result.parameters)
        report["other_actions"] = {
            "reference": str(out / f"{name}_reference.npz"),
            "error_mm": mean_distance(other.points, points),
        }
    write_json(out / f"{robot}_calibration.json", report, indent=2)
    console.print_json(json.dumps(report))


def _box(text: str, option: str, *, positive: bool = False, below: float | None = None):
    """A search box "LOW,HIGH" with 0 <= LOW (0 < LOW if `positive`) < HIGH (< `below`);
    BadParameter otherwise."""
    low, high = numbers_list(text, option, count=2)
    floor_met = low > 0.0 if positive else low >= 0.0
    if not (floor_met and low < high and (below is None or high < below)):
        bound = f" < {below:g}" if below is not None else ""
        first = "0 < LOW" if positive else "0 <= LOW"
        raise typer.BadParameter(f"{option}: need {first} < HIGH{bound}, got {text}")
    return low, high


def _fitted_parameters(path: Path) -> dict[str, float]:
    """The "parameters" of a calibration report; BadParameter if it holds none."""
    from pliant.errors import ModelError
    from pliant.proxy.calibrate import fitted_proxy

    try:
        keywords = fitted_proxy(json.loads(path.read_text()))
    except (ValueError, ModelError):
        raise typer.BadParameter(f"--start: {path} is not a calibration report") from None
    keywords.pop("contact", None)  # how it touched, not a parameter of the search
    keywords.pop("neutral", None)
    return keywords


def _actions(robot: str, text: str | None) -> list:
    """The action sequence: Multigait "4,0,0,2" (discrete), Trunk "0,0.2,0,0.2,0;..." (one
    continuous action of 5 values per group); None: the robot's default sequence."""
    from pliant.transfer.proxy import SEQUENCES

    if text is None:
        return list(SEQUENCES[robot])
    if robot == "multigait":
        values = numbers_list(text, "--actions")
        if not all(v.is_integer() and 0 <= v < 6 for v in values):
            raise typer.BadParameter(f"--actions: Multigait actions are integers in [0, 6): {text}")
        return [int(v) for v in values]
    return [numbers_list(group, "--actions", count=5) for group in text.split(";")]


@app.command()
def transfer(
    robot: Annotated[
        str, typer.Argument(help="multigait or trunk", callback=one_of("multigait", "trunk"))
    ],
    actions: Annotated[
        str | None,
        typer.Option(
            help="action sequence on the proxy: multigait '4,0,0,2,5,1,3,4' (the default),"
            " trunk 'a1;a2;...' with 5 values each (default: bend onto the cube, push along x)"
        ),
    ] = None,
    policy: Annotated[
        Path | None,
        typer.Option(
            help="a policy trained on the proxy env by `pliant train` (its folder or model.zip,"
            " with meta.json and vecnormalize.pkl beside it), a bare SB3 PPO .zip, or a kept"
            " policy.npz (`pliant export-policy`) or its folder"
        ),
    ] = None,
    steps: Annotated[int, option("steps of --policy", at_least_one)] = 8,
    proxy: Annotated[
        Path | None,
        typer.Option(
            help="a calibration report (JSON): the proxy with its fitted parameters and its"
            " contact, for --actions (a --policy brings the proxy it was trained on)",
            exists=True,
            dir_okay=False,
        ),
    ] = None,
    time_register: Annotated[
        int | None, typer.Option(help="proxy steps between realignments (0: never)")
    ] = None,
    inverse_steps: Annotated[
        int | None, option("steps of the inverse look-ahead", at_least_one)
    ] = None,
    gain: Annotated[
        float | None,
        typer.Option(help="s, the scale on the inverse model's actuation (the filter's s a_inv)"),
    ] = None,
    angle_gain: Annotated[
        float | None, typer.Option(help="Multigait corrector's gain (0: no correction)")
    ] = None,
    feedforward: Annotated[
        float | None,
        typer.Option(
            help="Multigait: weight in [0, 1] of the proxy's commands fed forward (1: open loop)"
        ),
    ] = None,
    prior_weight: Annotated[
        float | None,
        typer.Option(
            help="Multigait: the inverse QP's pull towards the proxy's commands mapped onto the"
            " chambers (a relative weight; 0, the thesis' loop, pulls towards zero force)"
        ),
    ] = None,
    lookahead_friction: Annotated[
        bool | None,
        typer.Option(help="friction in the inverse look-ahead (default: the robot's gains)"),
    ] = None,
    follow_shape: Annotated[
        bool | None,
        typer.Option(
            help="Multigait: the inverse model follows the proxy's shape, its goals moved along"
            " the floor onto the FEM's points (the travel left to the FEM's friction)"
        ),
    ] = None,
    rest_offset: Annotated[
        bool | None,
        typer.Option(
            help="Trunk: the FEM follows the proxy's displacements from its own starting shape"
            " (the goals carry the models' gap at the start)"
        ),
    ] = None,
    inverse_model: Annotated[
        str | None,
        typer.Option(
            help="'qp' (the inverse QP's look-ahead from the FEM's state), 'twin' (the"
            " authors' inverse scene: a second FEM under the inverse QP, registered on the FEM"
            " at the realignments) or 'sensitivity' (bounded least squares on the FEM step's"
            " actuation Jacobian, roll-outs with its friction)"
        ),
    ] = None,
    matched: Annotated[
        str | None,
        option(
            "multigait: the matched points, the skeleton's nodes at mid-thickness ('axis',"
            " the default) or under them on the underside ('underside', the authors' effectors)",
            one_of("axis", "underside"),
        ),
    ] = None,
    goal: Annotated[
        str | None,
        typer.Option(help="trunk: the goal's offset from the cube's start, 'x,z' mm (25,-10)"),
    ] = None,
    gif: Annotated[bool, typer.Option(help="also write a GIF (FEM beside proxy)")] = False,
    out: OutFolder = Path("out/proxy"),
) -> None:
    """Transfer ROBOT's proxy strategy to its FEM model (thesis §4.1.1, Fig. 4.2): inverse QP
    on the matched points, realignment, actuation correction; OUT/ROBOT_transfer.json and .png
    (and .gif)."""
    import dataclasses
    import sys

    from pliant.transfer.proxy import GAINS, TRANSFERS, frame, plot_transfer

    sequence = None if policy is not None else _actions(robot, actions)
    changes = {
        k: v
        for k, v in (
            ("time_register", time_register),
            ("inverse_steps", inverse_steps),
            ("gain", gain),
            ("angle_gain", angle_gain),
            ("lookahead_friction", lookahead_friction),
            ("feedforward", feedforward),
            ("prior_weight", prior_weight),
            ("follow_shape", follow_shape),
            ("inverse_model", inverse_model),
            ("rest_offset", rest_offset),
        )
        if v is not None
    }
    options: dict = {"gains": dataclasses.replace(GAINS[robot], **changes)}
    if matched is not None:
        if robot != "multigait":
            raise typer.BadParameter("--matched is the multigait's")
        options["matched"] = matched
    if goal is not None:
        if robot != "trunk":
            raise typer.BadParameter("--goal is the trunk's")

        options["goal_offset"] = tuple(numbers_list(goal, "--goal", count=2))
    if proxy is not None:
        from pliant.errors import ModelError
        from pliant.proxy.calibrate import fitted_proxy

        if policy is not None:
            raise typer.BadParameter("--proxy: a --policy brings the proxy it was trained on")
        try:
            options["env_kwargs"] = fitted_proxy(json.loads(proxy.read_text()))
        except (ValueError, ModelError) as exc:
            raise typer.BadParameter(f"--proxy: {proxy}: {exc}") from None
    chooser = None
    if policy is not None:
        from pliant.learn.evaluate import load_policy

        saved = load_policy(policy, algo="PPO")
        options["env_kwargs"] = saved.env_kwargs
        normalize = saved.normalize_obs or (lambda obs: obs)

        def chooser(obs):
            return saved.model.predict(normalize(obs), deterministic=True)[0]

    loop = TRANSFERS[robot](**options)
    frames, cameras = [], {}

    def progress(k: int, record) -> None:
        console.print(
            f"step {k}: proxy {record.proxy_reward:+.4f}  FEM {record.fem_reward:+.4f}"
            f"  tracking {record.tracking_error:.2f} mm" + ("  (realigned)" * record.realigned)
        )
        if gif:
            frames.append(frame(loop, cameras))

    result = loop.run(sequence, policy=chooser, steps=steps, progress=progress)
    out.mkdir(parents=True, exist_ok=True)
    report = {"command": "pliant " + " ".join(sys.argv[1:]), **result.to_dict()}
    write_results(out / f"{robot}_transfer.json", report)  # its trajectories at 7 digits
    plot_transfer(result, out / f"{robot}_transfer.png")
    if gif and frames:
        from pliant.viz.video import save_gif

        save_gif(frames, out / f"{robot}_transfer.gif", fps=2)
    console.print(
        f"proxy {result.proxy_return:+.4f}  FEM {result.fem_return:+.4f}  relative difference"
        f" {100 * result.relative_difference:.1f} %  ({result.wall_time:.0f} s)"
    )
