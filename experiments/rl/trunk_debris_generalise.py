"""TrunkSpaceDebris: the trained policy on placements outside its training's draw (issue #16;
the thesis validates "using cube positions and sizes that were not included in the training
set").

    PYTHONPATH=. python experiments/rl/trunk_debris_generalise.py \
        [--policy runs/trunk_debris_ppo_catchable_course40_bc/final] [--tests 100]

The policy folder is what ``trunk_debris_ppo.py --variant catchable_course40 --bc ...
--steps 102400`` leaves (not committed: its command reproduces it). Each setting widens one
thing of the training's draw (35-40 mm cubes at z 75-95 mm, gap 15-20 mm, along +x): the
heights to 65-105 mm and the gaps to 10-20 mm, or the direction to +-15 degrees about the
trunk. Deterministic actions, seeds 50000 on (training drew from 0, the tests from 30000),
scored by the catch test. Writes experiments/results/rl/trunk_debris_generalise.json.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from pliant.envs import make
from pliant.files import write_json
from pliant.learn.evaluate import load_policy, run_episodes

RESULTS = Path("experiments/results/rl/trunk_debris_generalise.json")
SETTINGS = {
    "wider_heights_and_gaps": {"z_low": 65.0, "z_high": 105.0, "gap_low": 10.0, "gap_high": 20.0},
    "turned_15_degrees": {"azimuth_range": float(np.radians(15.0))},
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--policy", type=Path, default=Path("runs/trunk_debris_ppo_catchable_course40_bc/final")
    )
    parser.add_argument("--tests", type=int, default=100)
    args = parser.parse_args()
    policy = load_policy(args.policy)
    summary = {
        "command": "PYTHONPATH=. python experiments/rl/trunk_debris_generalise.py"
        f" --policy {args.policy} --tests {args.tests}",
        "training_env_kwargs": policy.env_kwargs,
        "settings": {},
    }
    for name, change in SETTINGS.items():
        env = make("pliant/TrunkSpaceDebris-v0", **{**policy.env_kwargs, **change})
        clock = time.perf_counter()
        result = run_episodes(
            policy.model, env, args.tests, normalize_obs=policy.normalize_obs, seed=50_000
        )
        env.close()
        summary["settings"][name] = {
            "change": change,
            "catch_rate": result.success_rate,
            "diverged": result.diverged,
            "mean_return": result.mean_return,
            "wall_seconds": time.perf_counter() - clock,
            "catches": result.successes,
        }
        write_json(RESULTS, summary)
        print(name, summary["settings"][name]["catch_rate"], flush=True)


if __name__ == "__main__":
    main()
