"""A push learnt directly on the FEM Trunk, replayed on the proxy (docs/proxy.md, the one-goal
comparison): the FEM policy of experiments/proxy/fixed_goal.py (GOAL, SEED) plays its greedy
episode on the FEM; after each step the cables it reached, with the same base command, are
the proxy's action in the FEM's action space (TrunkPushProxy's actions="cables": the
calibration's cables -> bendings map), and the proxy replays them. Both
cubes' tracks and final distances to the goal are printed; `--proxy JSON` passes keywords to
the proxy (e.g. '{"contact": "surface"}', '{"friction": 0.6}', a calibration's parameters).

    python experiments/proxy/fixed_goal.py --goal x25 --seed 2 --side fem   # the policy
    python experiments/proxy/replay_push.py --goal x25 --seed 2 [--proxy JSON]
"""

from __future__ import annotations

import argparse
import json
import warnings

import numpy as np

from pliant.envs.trunk_push_proxy import CABLE_COURSES
from pliant.learn.evaluate import load_policy
from pliant.learn.vec import make_env
from pliant.transfer.fem_rl import FEM_ENV, FEM_KWARGS, goal_kwargs
from pliant.transfer.fem_rl import FIXED_GOAL_OUT as OUT
from pliant.transfer.fem_rl import FIXED_GOALS as GOALS
from pliant.transfer.rl import SETTINGS


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--goal", choices=sorted(GOALS), default="x25")
    parser.add_argument("--seed", type=int, default=2)
    parser.add_argument("--proxy", type=json.loads, default={}, help="proxy keywords (JSON)")
    args = parser.parse_args()
    warnings.simplefilter("ignore")
    saved = load_policy(OUT / args.goal / f"seed{args.seed}" / "fem")
    task = goal_kwargs(GOALS[args.goal])
    fem = make_env(FEM_ENV, {**FEM_KWARGS, **task})
    proxy_kwargs = {**SETTINGS["trunk"]["env_kwargs"], **task, **args.proxy, "actions": "cables"}
    proxy = make_env(SETTINGS["trunk"]["env_id"], proxy_kwargs)
    reach = CABLE_COURSES * proxy_kwargs["bend_limit"]  # the FEM's courses, 14 and 8 mm

    obs, _ = fem.reset(seed=0)
    replay = []
    while True:
        action = saved.model.predict(saved.normalize_obs(obs), deterministic=True)[0]
        obs, _, terminated, truncated, _ = fem.step(action)
        cables = fem.unwrapped.state.displacement
        replay.append(np.r_[np.clip(2.0 * cables / reach - 1.0, -1.0, 1.0), action[-1]])
        print(
            f"FEM   step {len(replay)}: cables {np.round(cables, 1).tolist()} mm, cube (x, z) "
            f"{np.round(fem.unwrapped.cube()[[0, 2]], 1).tolist()}, "
            f"{fem.unwrapped.distance():.1f} mm from the goal"
        )
        if terminated or truncated:
            break
    proxy.reset(seed=0)
    for k, action in enumerate(replay):
        proxy.step(action)
        bendings = proxy.unwrapped.commands[:4] / proxy_kwargs["bend_limit"]
        print(
            f"proxy step {k + 1}: bendings {np.round(bendings, 2).tolist()}, cube (x, z) "
            f"{np.round(proxy.unwrapped.cube()[[0, 2]], 1).tolist()}, "
            f"{proxy.unwrapped.distance():.1f} mm from the goal"
        )


if __name__ == "__main__":
    main()
