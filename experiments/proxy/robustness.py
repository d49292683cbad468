"""Robustness to the proxy's accuracy (thesis §4.1.3, Fig. 4.5 A-B), at a small scale: the
Multigait proxy's six calibrated parameters p become p (1 + level U(-1, 1)) (one draw, the
same for every level, scaled), PPO learns again on each degraded proxy, and each policy is
transferred to the FEM Multigait; the thesis finds that the reward still increases in every
case, levels 0.001 to 0.1.

    python experiments/proxy/robustness.py [--levels 0.001,0.01,0.1] [--env-steps 1440]
        [--transfer-steps 4]

Results: experiments/results/proxy/robustness.json and .png (forward travel against time, FEM
and proxy, one line per level); each policy in experiments/results/proxy/rl_multigait_noiseL/.

At a larger scale, around another calibration (its parameters and contact), several draws a
level (draw d: the noise of seed d, PPO seed d), each transferred open loop:

    python experiments/proxy/robustness.py --parameters REPORT.json --draws 3 \
        --feedforward 1 --tag _surface

writes robustness_surface.json and .png, the policies in rl_multigait_surface_noiseL_drawD/;
a run that stops goes on from the rows its report holds (the policy it was training is
trained again from the start).

The Trunk (thesis Fig. 4.6 A-B: "for the different proxies, the results are the same as for
the Multigait"), around the axial proxy with its cube fitted on the FEM's pushes, PPO as the
pipeline's (the FEM's cables as actions, log_std_init -1), at the proxy's own 0.03 s step
(20400 environment steps, 2.04e5 simulation steps), each policy transferred by the inverse-QP
loop on the 20 evaluation goals (experiments/proxy/vs_fem_rl.py's):

    python experiments/proxy/robustness.py --robot trunk --draws 2

writes robustness_trunk.json and .png (the mean final cube-goal distance on each degraded
proxy and on the FEM following it, against the level; doing nothing leaves 21.3 mm), the
policies in rl_trunk_trunk_noiseL_drawD/. Level 0 (the proxy itself) is the pipeline's own
run of that seed (``proxy/rl.py --dt 0.03``, rl_trunk_axial_cables_dt03[_seedS]/).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from pliant._proxsuite import BUILD
from pliant.files import write_results
from pliant.learn.evaluate import load_policy
from pliant.transfer.fem_rl import summary, transfer_proxy_policy
from pliant.transfer.proxy import FORWARD, MULTIGAIT_GAINS, multigait_transfer
from pliant.transfer.reports import EARLIER_BUILD
from pliant.transfer.rl import degraded, learn
from pliant.viz import save_figure

OUT = Path("experiments/results/proxy")
#: the Trunk's study: the proxy it degrades, and its PPO settings (the pipeline's)
TRUNK_PARAMETERS = Path("experiments/proxy/push_cocontraction/trunk-push_calibration.json")
TRUNK_HYPERPARAMS = {"policy_kwargs": {"log_std_init": -1}}
#: the Trunk's cube-goal distance on the 20 evaluation goals when nothing moves
TRUNK_STILL_MM = 21.3


def transfer(policy_dir: Path, steps: int, feedforward: float = 0.0) -> dict:
    """The policy's strategy on its (degraded) proxy, followed by the FEM Multigait (by the
    inverse-QP loop, blended with `feedforward` of the proxy's actuation)."""
    saved = load_policy(policy_dir)
    gains = replace(MULTIGAIT_GAINS, feedforward=feedforward)
    loop = multigait_transfer(gains=gains, env_kwargs=saved.env_kwargs)
    result = loop.run(
        policy=lambda obs: saved.model.predict(saved.normalize_obs(obs), deterministic=True)[0],
        steps=steps,
    )
    proxy, fem = np.asarray(result.proxy_trajectory), np.asarray(result.fem_trajectory)
    return {
        "actions": [s.action for s in result.steps],
        "proxy_travel_mm": result.proxy_return,
        "fem_travel_mm": result.fem_return,
        "times": result.times,
        "proxy_forward_mm": ((proxy - proxy[0]) @ FORWARD).tolist(),
        "fem_forward_mm": ((fem - fem[0]) @ FORWARD).tolist(),
        "wall_seconds": result.wall_time,
    }


def plot(rows: list[dict], path: Path) -> None:
    from pliant.viz.render import offscreen_figure

    fig = offscreen_figure(10.0, 4.0)
    left, right = fig.subplots(1, 2)
    levels = sorted({row["level"] for row in rows})
    for row in rows:
        t, k = row["transfer"], levels.index(row["level"])
        label = f"noise {row['level']:g}" if row.get("draw", 0) == 0 else None
        left.plot(t["times"], t["fem_forward_mm"], f"C{k}-", label=label)
        right.plot(t["times"], t["proxy_forward_mm"], f"C{k}-", label=label)
    for ax, title in ((left, "A) FEM following each proxy"), (right, "B) each proxy")):
        ax.set_xlabel("time (s)")
        ax.set_ylabel("forward travel (mm)")
        ax.set_title(title)
        ax.legend(fontsize=8)
    fig.tight_layout()
    save_figure(fig, path, dpi=120)


def trunk_transfer_summary(policy_dir: Path) -> dict:
    """The Trunk policy on the FEM, through the transfer loop, for each evaluation goal."""
    clock = time.perf_counter()
    goals = transfer_proxy_policy(policy_dir)
    return {
        "fem": summary([g["fem_distance"] for g in goals]),
        "proxy": summary([g["proxy_distance"] for g in goals]),
        "goals": goals,
        "wall_seconds": time.perf_counter() - clock,
        "proxsuite_build": BUILD,  # the inverse QP's (pliant._proxsuite)
    }


def plot_trunk(rows: list[dict], path: Path) -> None:
    """Mean final cube-goal distance against the noise level: each proxy's own episodes and
    the FEM following it (one marker a draw)."""
    from pliant.viz.render import offscreen_figure

    fig = offscreen_figure(6.0, 4.0)
    ax = fig.subplots()
    levels = sorted({row["level"] for row in rows})
    for row in rows:
        x = levels.index(row["level"]) + 0.08 * (row.get("draw") or 0)
        first = row is rows[0]
        ax.plot(x, row["proxy_mean_final_distance_mm"], "C0o", label="proxy" if first else None)
        ax.plot(
            x,
            row["transfer"]["fem"]["mean_final_distance_mm"],
            "C1s",
            label="FEM following it" if first else None,
        )
    ax.axhline(TRUNK_STILL_MM, color="0.5", ls="--", label="doing nothing")
    ax.set_xticks(range(len(levels)), [f"{v:g}" for v in levels])
    ax.set_xlabel("noise level on the proxy's parameters")
    ax.set_ylabel("mean final cube-goal distance (mm)")
    ax.set_title("Trunk: 20 evaluation goals")
    ax.legend(fontsize=8)
    fig.tight_layout()
    save_figure(fig, path, dpi=120)


def retransfer(report: dict, path: Path, tag: str) -> None:
    """Transfer each row's Trunk policy again under this process's ProxQP build, the row's
    earlier FEM mean kept beside it (``earlier_fem_mean_mm``, ``earlier_build``), the report
    written back after each row; rows already transferred under this build are left alone, so
    a stopped run goes on."""
    for row in report["rows"]:
        earlier = row["transfer"]
        if earlier.get("proxsuite_build") == BUILD:
            continue
        name = f"rl_trunk{tag}_noise{row['level']:g}_draw{row['draw']}"
        row["transfer"] = trunk_transfer_summary(OUT / name)
        row["transfer"]["earlier_fem_mean_mm"] = earlier["fem"]["mean_final_distance_mm"]
        row["transfer"]["earlier_build"] = earlier.get("proxsuite_build", EARLIER_BUILD)
        fem = row["transfer"]["fem"]["mean_final_distance_mm"]
        print(f"{name}: FEM {fem:.2f} mm (earlier {row['transfer']['earlier_fem_mean_mm']:.2f})")
        write_results(path, report)
    plot_trunk(report["rows"], path.with_suffix(".png"))


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--robot", choices=("multigait", "trunk"), default="multigait")
    parser.add_argument("--levels", default="0.001,0.01,0.1")
    parser.add_argument(
        "--env-steps", type=int, default=None, help="default 1440 (Multigait), 20400 (Trunk)"
    )
    parser.add_argument("--dt", type=float, default=None, help="the proxy's step (Trunk: 0.03)")
    parser.add_argument("--transfer-steps", type=int, default=4)
    parser.add_argument("--parameters", type=Path, default=None, help="a calibration report")
    parser.add_argument("--draws", type=int, default=None, help="draws a level (seeds 0..)")
    parser.add_argument("--feedforward", type=float, default=0.0, help="transfer's blend")
    parser.add_argument("--tag", default="", help="suffix of the report and policy folders")
    parser.add_argument(
        "--retransfer",
        action="store_true",
        help="Trunk: transfer the report's policies again (not learnt again) where the row's"
        " transfer ran under another ProxQP build than this process's; resumes",
    )
    args = parser.parse_args()
    # each report records the command that writes it, the policies' reports as well
    command = " ".join(["python experiments/proxy/robustness.py", *sys.argv[1:]])
    trunk = args.robot == "trunk"
    if trunk:
        args.parameters = args.parameters or TRUNK_PARAMETERS
        args.dt = args.dt or 0.03
        args.tag = args.tag or "_trunk"
    args.env_steps = args.env_steps or (20400 if trunk else 1440)
    path = OUT / f"robustness{args.tag}.json"
    # One draw (seed 0) without --draws, named as before; a run with --draws resumes.
    draws = [None] if args.draws is None else list(range(args.draws))
    earlier = json.loads(path.read_text()) if args.draws is not None and path.exists() else None
    rows = earlier["rows"] if earlier else []
    if args.retransfer:
        if not trunk or not rows:
            parser.error("--retransfer takes --robot trunk and --draws, and a report with rows")
        retransfer(earlier, path, args.tag)
        return
    done = {(row["level"], row.get("draw")) for row in rows}
    base = None if args.parameters is None else json.loads(args.parameters.read_text())
    for level in (float(v) for v in args.levels.split(",")):
        for draw in draws:
            if (level, draw) in done:
                continue
            clock = time.perf_counter()
            tag = f"{args.tag}_noise{level:g}" + ("" if draw is None else f"_draw{draw}")
            report = learn(
                args.robot,
                env_steps=args.env_steps,
                noise=level,
                seed=draw or 0,
                tag=tag,
                command=command,
                parameters=args.parameters,
                **(
                    {"cables": True, "dt": args.dt, "hyperparams": TRUNK_HYPERPARAMS}
                    if trunk
                    else {}
                ),
            )
            fitted = base and base["parameters"]
            row = {
                "level": level,
                "draw": draw,
                "parameters": degraded(args.robot, level, draw or 0, fitted),
                "training_seconds": report["training_seconds"],
            }
            learned = report["evaluation"]["learned"]
            if trunk:
                row["proxy_mean_final_distance_mm"] = learned["mean_final_distance_mm"]
                row["proxy_solved"] = learned["solved"]
                row["transfer"] = trunk_transfer_summary(OUT / f"rl_trunk{tag}")
                fem = row["transfer"]["fem"]
                message = (
                    f"proxy {row['proxy_mean_final_distance_mm']:.1f} mm; FEM following it"
                    f" {fem['mean_final_distance_mm']:.1f} mm ({fem['solved_under_8mm']:.0%})"
                )
            else:
                row["proxy_episode_travel_mm"] = learned["travel_mm"]
                row["learned_actions"] = report["evaluation"]["learned_actions"]
                row["transfer"] = transfer(
                    OUT / f"rl_multigait{tag}", args.transfer_steps, args.feedforward
                )
                t = row["transfer"]
                message = (
                    f"proxy episode {row['proxy_episode_travel_mm']:.2f} mm; transfer proxy"
                    f" {t['proxy_travel_mm']:.2f} / FEM {t['fem_travel_mm']:.2f} mm"
                )
            row["wall_seconds"] = time.perf_counter() - clock
            rows.append(row)
            print(f"noise {level:g} draw {draw}: {message}", flush=True)
            report = {
                "command": command,
                "robot": args.robot,
                "env_steps": args.env_steps,
                "dt": args.dt,
                "transfer_steps": None if trunk else args.transfer_steps,
                "parameters": None if args.parameters is None else str(args.parameters),
                "feedforward": None if trunk else args.feedforward,
                "rows": rows,
            }
            write_results(path, report)
            (plot_trunk if trunk else plot)(rows, path.with_suffix(".png"))


if __name__ == "__main__":
    main()
