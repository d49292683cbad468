"""A policy learnt directly on the FEM Trunk, played closed loop on the proxy (docs/proxy.md,
"Is the proxy or PPO on it the gap?"): does the proxy reward what the FEM rewards?

At every step the proxy's observation (16 skeleton nodes, the cube, the goal) goes to the FEM
policy as if it were the FEM's (16 fibre points, the cube, the goal: the same quantities); its
action (absolute cable targets within 0.2 of the courses, and the base) drives the proxy
through the FEM's action space (TrunkPushProxyEnv's actions="cables": the calibration's
cables -> bendings map). On the 20 goals of experiments/proxy/vs_fem_rl.py (seeds 1000-1019),
beside the policy's own results on the FEM.

    python experiments/proxy/fem_policy_on_proxy.py experiments/results/proxy/fem_vs_proxy/std1 \
        [--parameters experiments/proxy/contraction/trunk_calibration.json]

Writes proxy_replay.json into the policy's folder (with --parameters: proxy_replay_fitted.json,
or proxy_replay_TAG.json with --tag TAG).
"""

from __future__ import annotations

import argparse
import json
import sys
import warnings
from pathlib import Path

import numpy as np

from pliant.learn.evaluate import load_policy
from pliant.learn.vec import make_env
from pliant.proxy.calibrate import fitted_proxy
from pliant.transfer.fem_rl import GOALS
from pliant.transfer.rl import SETTINGS, episode


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("policy", type=Path, help="a FEM policy's folder (proxy/vs_fem_rl.py)")
    parser.add_argument("--parameters", type=Path, default=None, help="a calibration JSON")
    parser.add_argument(
        "--tag", default="fitted", help="with --parameters: writes proxy_replay_TAG.json"
    )
    args = parser.parse_args()
    warnings.simplefilter("ignore")
    saved = load_policy(args.policy)
    fem_kwargs = saved.env_kwargs
    if fem_kwargs.get("planar"):
        raise SystemExit("a planar FEM policy: the proxy's cable actions are all eight")
    proxy_kwargs = {**SETTINGS["trunk"]["env_kwargs"], "actions": "cables"}
    if args.parameters is not None:
        proxy_kwargs.update(fitted_proxy(json.loads(args.parameters.read_text())))
    proxy = make_env(SETTINGS["trunk"]["env_id"], proxy_kwargs)
    # the same action means the same cables only if the FEM's courses are the proxy's reach
    limit = proxy_kwargs["bend_limit"]
    courses = (fem_kwargs["max_long_displacement"], fem_kwargs["max_short_displacement"])
    if not np.allclose(courses, (70.0 * limit, 40.0 * limit)):
        raise SystemExit(f"the FEM policy's cable courses {courses} mm are not bend_limit {limit}")

    def choose(obs, k):
        return saved.model.predict(saved.normalize_obs(obs), deterministic=True)[0]

    rows = [episode(proxy, choose, s) for s in GOALS]
    own = json.loads((args.policy / "report.json").read_text())["rl_on_fem"]
    d = np.array([r["distance"] for r in rows])
    report = {
        "command": "python experiments/proxy/fem_policy_on_proxy.py " + " ".join(sys.argv[1:]),
        "policy": str(args.policy),
        "proxy_kwargs": proxy_kwargs,
        "on_the_proxy": {
            "mean_final_distance_mm": float(d.mean()),
            "median_final_distance_mm": float(np.median(d)),
            "solved_under_8mm": float(np.mean([r["solved"] for r in rows])),
            "episodes": rows,
        },
        "on_the_fem": {k: own[k] for k in own if k.endswith(("_mm", "8mm"))},
    }
    name = "proxy_replay.json" if args.parameters is None else f"proxy_replay_{args.tag}.json"
    (args.policy / name).write_text(json.dumps(report, indent=1))
    print(json.dumps({k: report[k] for k in ("on_the_fem",)}))
    print(json.dumps({k: v for k, v in report["on_the_proxy"].items() if k != "episodes"}))


if __name__ == "__main__":
    main()
