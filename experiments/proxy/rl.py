"""PPO on the beam-skeleton proxies (thesis §4.1.3: "the PPO algorithm determines a strategy on
the proxy that solves the task", about 2e4 simulation steps for the Multigait, 2e5 for the
Trunk), with Pliant's training stack (checkpoints, evaluation curve, VecNormalize).

    python experiments/proxy/rl.py multigait [--env-steps 3000] [--seed 0] [--points-only]
    python experiments/proxy/rl.py trunk [--env-steps 6700] [--seed 0]

``--noise LEVEL`` learns on a degraded proxy (experiments/proxy/robustness.py);
``--parameters CALIBRATION.json`` on a proxy of other fitted parameters, e.g. the 16-action
calibration's (``--parameters experiments/proxy/patterns/multigait-patterns_calibration.json
--tag _patterns``); ``--contact surface`` on a proxy touching through the FEM's skinned surface
(a calibration report of such a proxy says so itself); ``--planar`` restricts the Trunk's
bendings to the floor's plane (towards +-x; Box(3) actions); ``--cables`` drives the Trunk
proxy through the FEM's action space (8 absolute cable targets and the base, Box(9), mapped to
the bendings); ``--dt 0.03`` steps the proxy in 0.03 s sub-steps (10 to the Trunk's 0.3 s
step, where 30 of 0.01 s is the default; its simulation steps count as such).

Multigait (pliant/MultigaitProxy-v0, 12 steps of 0.6 s, Discrete(6)): the greedy policy's
forward travel over an episode beside the hand gait's (rear, centre, front inflated, then
deflated in that order) and random actions'. Trunk (pliant/TrunkPushProxy-v0, 10 steps of
0.3 s, Box(5), goal drawn in (x, z)): on 20 fixed goals, the final cube-goal distance and the
share solved (< 8 mm) beside doing nothing and random actions.

The run folder (checkpoints, ``--resume``) is runs/proxy_rl_ROBOT; the final policy, the
report (JSON) and the learning curve (PNG) go to experiments/results/proxy/rl_ROBOT/. The
settings and the run are :mod:`pliant.transfer.rl`'s, which the other proxy studies share.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from pliant.transfer.rl import SAC_SETTINGS, SETTINGS, learn


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("robot", choices=sorted(SETTINGS))
    parser.add_argument("--env-steps", type=int, default=None)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--points-only", action="store_true", help="the thesis' observation")
    parser.add_argument("--noise", type=float, default=0.0, help="degraded proxy's level")
    parser.add_argument("--bend-limit", type=float, default=None, help="trunk (default 0.2)")
    parser.add_argument("--resume", action="store_true")
    parser.add_argument(
        "--algo", choices=("PPO", "SAC"), default="PPO", help="SAC: the Trunk only (a departure)"
    )
    parser.add_argument("--tag", default="", help="suffix of the run and result folders")
    parser.add_argument(
        "--parameters", type=Path, default=None, help="proxy parameters: a calibration JSON"
    )
    parser.add_argument(
        "--contact", choices=("nodes", "surface"), default=None, help="the proxy's contact"
    )
    parser.add_argument(
        "--planar", action="store_true", help="trunk: bendings towards +-x only (a priori)"
    )
    parser.add_argument(
        "--cables",
        action="store_true",
        help="trunk: the FEM's action space (8 cables and the base) mapped to the bendings",
    )
    parser.add_argument(
        "--hyperparams",
        type=json.loads,
        default=None,
        help='JSON over the settings\' SB3 keywords, e.g. {"n_epochs": 5}',
    )
    parser.add_argument(
        "--dt",
        type=float,
        default=None,
        help="the proxy's time step (s); the environment's step keeps its duration",
    )
    args = parser.parse_args()
    if args.planar and args.robot != "trunk":
        parser.error("--planar restricts the Trunk's bendings")
    if args.algo == "SAC" and args.robot not in SAC_SETTINGS:
        parser.error(f"--algo {args.algo} has no settings for the {args.robot}")
    report = learn(
        args.robot,
        env_steps=args.env_steps,
        seed=args.seed,
        points_only=args.points_only,
        noise=args.noise,
        bend_limit=args.bend_limit,
        tag=args.tag,
        resume=args.resume,
        parameters=args.parameters,
        contact=args.contact,
        algo=args.algo,
        planar=args.planar,
        hyperparams=args.hyperparams,
        cables=args.cables,
        dt=args.dt,
        command="python experiments/proxy/rl.py " + " ".join(sys.argv[1:]),
    )
    print(json.dumps({k: v for k, v in report.items() if k != "curve"}, indent=1))


if __name__ == "__main__":
    main()
