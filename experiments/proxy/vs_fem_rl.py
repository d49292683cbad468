"""The proxy pipeline against RL directly on the FEM (thesis §4.1.3, Trunk pushing a cube: the
proxy method ends 2 mm from the goal, PPO on the FEM with the same budget 4.5 mm).

1. PPO directly on the FEM Trunk (pliant/TrunkPush-v0 with the proxy environment's 0.3 s
   steps: 30 sub-steps of 0.01 s) with the proxy's PPO settings and budget (experiments/
   proxy/rl.py: MLP 128 x 128, n_steps 200, batch 50, gamma 0.95, observations and rewards
   normalised; 6700 environment steps = 2e5 simulation steps). The proxy's a-priori amplitude
   limit (bend_limit 0.2) becomes the cables' courses at 0.2 of theirs (14 and 8 mm); the
   cables are absolute targets, reached at 1 mm a sub-step.
2. The proxy's policy (experiments/results/proxy/rl_trunk, trained on the proxy with that
   budget) transferred to the FEM by `pliant proxy transfer`'s loop (inverse QP on the 30
   skeleton points; docs/proxy.md).

Each FEM episode is run as the environment runs it: 10 steps of 0.3 s, ended at the first step
that leaves the cube within 8 mm of the goal (the same for both methods).

Both are evaluated on the same 20 goals (the environments' seeds 1000-1019, which draw the same
goal offsets in both): the FEM's final cube-goal distance in the floor's plane, and the share
under 8 mm. Training checkpoints in runs/proxy_vs_fem_rl (`--resume` goes on from the last);
results in experiments/results/proxy/fem_vs_proxy/.

    python experiments/proxy/vs_fem_rl.py [--env-steps 6700] [--resume]
    # another proxy policy through the same transfer and goals (report_NAME.json)
    python experiments/proxy/vs_fem_rl.py --transfer-only experiments/results/proxy/rl_trunk_20k
    # another seed (results in fem_vs_proxy/seed1/), its proxy policy trained with that seed
    python experiments/proxy/rl.py trunk --seed 1 --tag _seed1
    python experiments/proxy/vs_fem_rl.py --seed 1 \
        --proxy-policy experiments/results/proxy/rl_trunk_seed1
    # the FEM's cube imposed on the proxy every 3 steps (the thesis' 10: never in an episode)
    python experiments/proxy/vs_fem_rl.py --transfer-only experiments/results/proxy/rl_trunk \
        --time-register 3
    # the a priori planar restriction on both sides (bendings / cables towards +-x only)
    python experiments/proxy/rl.py trunk --parameters \
        experiments/proxy/contraction/trunk_calibration.json --planar --tag _contraction_planar
    python experiments/proxy/vs_fem_rl.py --planar \
        --proxy-policy experiments/results/proxy/rl_trunk_contraction_planar
    # SAC on both sides (a departure: the thesis used PPO), results in fem_vs_proxy/sac/
    python experiments/proxy/rl.py trunk --algo SAC --env-steps 6800 --tag _sac
    python experiments/proxy/vs_fem_rl.py --algo SAC \
        --proxy-policy experiments/results/proxy/rl_trunk_sac
    # the FEM as its own coarse model: PPO on the FEM stepped at 0.03 s, evaluated at 0.01 s
    python experiments/proxy/vs_fem_rl.py --fem-dt 0.03 --env-steps 20400 --tag _dt03 \
        --skip-pipeline
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import warnings
from pathlib import Path

from pliant import configure_threads
from pliant._proxsuite import BUILD
from pliant.transfer.fem_rl import (
    FEM_ENV,
    GOALS,
    OUT,
    evaluate_on_fem,
    fem_kwargs,
    suffix,
    summary,
    train_on_fem,
    transfer_proxy_policy,
)
from pliant.transfer.rl import SETTINGS


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--env-steps", type=int, default=SETTINGS["trunk"]["env_steps"])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--resume", action="store_true")
    parser.add_argument("--algo", choices=("PPO", "SAC"), default="PPO", help="RL on the FEM")
    parser.add_argument(
        "--proxy-policy",
        type=Path,
        default=Path("experiments/results/proxy/rl_trunk"),
        help="the proxy's policy the pipeline transfers",
    )
    parser.add_argument(
        "--transfer-only", type=Path, default=None, help="only transfer this proxy policy"
    )
    parser.add_argument(
        "--time-register",
        type=int,
        default=None,
        help="with --transfer-only: proxy steps between realignments (default the thesis' 10)",
    )
    parser.add_argument(
        "--rest-offset",
        action="store_true",
        help="with --transfer-only: the FEM follows the proxy's displacements (TransferGains)",
    )
    parser.add_argument(
        "--planar",
        action="store_true",
        help="RL on the FEM drives the -x/+x cables only (TrunkPush's planar; results in"
        " fem_vs_proxy/planar[_seedS]/)",
    )
    parser.add_argument(
        "--hyperparams",
        type=json.loads,
        default=None,
        help="JSON over proxy/rl.py's PPO settings, for RL on the FEM (as its --hyperparams)",
    )
    parser.add_argument(
        "--tag", default="", help="prefix of the FEM run's folders (e.g. _std: fem_vs_proxy/std/)"
    )
    parser.add_argument(
        "--fem-dt",
        type=float,
        default=None,
        help="RL on the FEM stepped at this dt (s) instead of 0.01; evaluated at 0.01",
    )
    parser.add_argument(
        "--fem-cable-step",
        type=float,
        default=None,
        help="RL on the FEM with cables changing at most this much a simulation step (mm;"
        " default the Trunk's 1); evaluated at 1",
    )
    parser.add_argument(
        "--skip-pipeline", action="store_true", help="RL on the FEM only: no proxy transfer"
    )
    args = parser.parse_args()
    if args.tag and not args.tag.startswith("_"):
        parser.error("--tag starts with '_'")
    if args.transfer_only is not None and (args.planar or args.hyperparams or args.tag):
        parser.error("--planar, --hyperparams and --tag are for RL on the FEM, not --transfer-only")
    warnings.simplefilter("ignore")
    configure_threads(torch_threads=1)
    OUT.mkdir(parents=True, exist_ok=True)
    if args.transfer_only is not None:
        rows = transfer_proxy_policy(args.transfer_only, args.time_register, args.rest_offset)
        trained = json.loads((args.transfer_only / "report.json").read_text())
        report = {
            "command": "python experiments/proxy/vs_fem_rl.py " + " ".join(sys.argv[1:]),
            "policy": str(args.transfer_only),
            "proxy_env_steps": trained["env_steps"],
            "proxy_simulation_steps": trained["simulation_steps"],
            "proxy_training_seconds": trained["training_seconds"],
            "time_register": args.time_register or 10,
            "rest_offset": args.rest_offset,
            # the inverse QP's build: the baseline is reproducible bit for bit (pliant._proxsuite)
            "proxsuite_build": BUILD,
            "fem": summary([r["fem_distance"] for r in rows]),
            "proxy": summary([r["proxy_distance"] for r in rows]),
            "transfers": rows,
        }
        name = args.transfer_only.name
        if args.time_register is not None:
            name += f"_register{args.time_register}"
        if args.rest_offset:
            name += "_rest_offset"
        (OUT / f"report_{name}.json").write_text(json.dumps(report, indent=1))
        print(json.dumps({k: report[k] for k in ("fem", "proxy")}))
        return
    name = args.tag + suffix(args.algo, args.seed, args.planar)
    out = OUT / name[1:] if name else OUT
    out.mkdir(parents=True, exist_ok=True)
    run_dir, trained = train_on_fem(
        args.env_steps,
        args.seed,
        args.resume,
        args.algo,
        args.planar,
        args.hyperparams,
        args.tag,
        args.fem_dt,
        args.fem_cable_step,
    )
    for f in ("model.zip", "vecnormalize.pkl", "meta.json"):
        shutil.copy(run_dir / "final" / f, out / f)
    shutil.copy(run_dir / "learning_curve.png", out / "fem_learning_curve.png")
    direct = evaluate_on_fem(run_dir / "final", args.planar)
    training_kwargs = fem_kwargs(args.planar, args.fem_dt, args.fem_cable_step)
    report = {
        "command": "python experiments/proxy/vs_fem_rl.py " + " ".join(sys.argv[1:]),
        "goals": f"seeds {GOALS.start}-{GOALS.stop - 1} of both environments",
        "training_seed": args.seed,
        "fem_env": FEM_ENV,
        "fem_env_kwargs": fem_kwargs(args.planar),
        "rl_on_fem": {
            "algo": args.algo,
            "hyperparams_over_settings": args.hyperparams,
            "training_env_kwargs": training_kwargs,
            "env_steps": trained["steps"],
            "simulation_steps": trained["steps"] * training_kwargs["substeps"],
            "training_seconds": trained["wall_seconds"],
            **summary([r["distance"] for r in direct]),
            "episodes": direct,
        },
        "proxy_pipeline": None,
        "proxsuite_build": BUILD,
        "thesis": {"proxy_pipeline_mm": 2.0, "rl_on_fem_mm": 4.5},
    }
    if not args.skip_pipeline:
        transferred = transfer_proxy_policy(args.proxy_policy)
        proxy_trained = json.loads((args.proxy_policy / "report.json").read_text())
        report["proxy_pipeline"] = {
            "policy": str(args.proxy_policy),
            "algo": proxy_trained.get("algo", "PPO"),
            "proxy_env_steps": proxy_trained["env_steps"],
            "fem": summary([r["fem_distance"] for r in transferred]),
            "proxy": summary([r["proxy_distance"] for r in transferred]),
            "transfers": transferred,
        }
    (out / "report.json").write_text(json.dumps(report, indent=1))
    print(json.dumps({k: v for k, v in report.items() if k not in ("rl_on_fem", "proxy_pipeline")}))
    print("RL on the FEM:", json.dumps(summary([r["distance"] for r in direct])))
    if report["proxy_pipeline"] is not None:
        print("proxy pipeline (FEM):", json.dumps(report["proxy_pipeline"]["fem"]))


if __name__ == "__main__":
    main()
