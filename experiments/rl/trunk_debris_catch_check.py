"""The programs the planner found (trunk_debris_expert.py) scored by the catch test.

    PYTHONPATH=. python experiments/rl/trunk_debris_catch_check.py [FOLDER ...]
        (default: experiments/results/rl/trunk_debris_expert)

Every program that met the environment's default success (the trunk on two faces of the cube
at the last step) in a results folder of trunk_debris_expert.py (``placements/`` and
``sweeps/``) is replayed from the same reset in ``pliant/TrunkSpaceDebris-v0`` with
``success="catch"`` (two opposite faces pressed, the cube off the hull, for the last 5 steps)
and the same keywords. Writes ``catch_check.json`` in each folder: per program the default
test's verdict, the catch test's, and the last step's faces, opposite faces, hull contact and
the steps held.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

import numpy as np

RESULTS = Path("experiments/results/rl/trunk_debris_expert")


def check_folder(env, folder: Path) -> dict:
    from pliant.robots.trunk_debris import beside_trunk

    programs = []
    for phase in ("placements", "sweeps"):
        for path in sorted((folder / phase).glob("*.json")):
            record = json.loads(path.read_text())
            if not record.get("success"):
                continue
            size, z, gap = record["cube_size"], record["z"], record["gap"]
            position = beside_trunk(size, z, gap, 0.0)
            env.reset(seed=record["seed"], options={"cube_size": size, "cube_position": position})
            info = {}
            for action in np.asarray(record["best"]["actions"], dtype=np.float32):
                _, _, terminated, _, info = env.step(action)
                if terminated or "diverged" in info:
                    break
            programs.append(
                {
                    "phase": phase,
                    "name": record["name"],
                    "faces_success": bool(record["success"]),
                    "catch": bool(info.get("is_success", False)),
                    "faces_at_end": info.get("faces"),
                    "opposite_faces": info.get("opposite_faces"),
                    "on_hull": info.get("on_hull"),
                    "held": info.get("held"),
                }
            )
            print(programs[-1], flush=True)
    return {
        "command": " ".join(
            ["PYTHONPATH=. python experiments/rl/trunk_debris_catch_check.py", *sys.argv[1:]]
        ),
        "env_kwargs": dict(env.spec.kwargs) if env.spec else {},
        "programs": programs,
        "faces_successes": len(programs),
        "catches": sum(p["catch"] for p in programs),
        "placements_with_a_catch": sorted({p["name"] for p in programs if p["catch"]}),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folders", nargs="*", type=Path, default=[RESULTS])
    args = parser.parse_args()

    import gymnasium as gym

    import pliant.envs  # noqa: F401  (registers the environments)

    for folder in args.folders:
        # The search's own keywords (its summary's), scored by the catch test.
        kwargs = json.loads((folder / "summary.json").read_text())["env_kwargs"]
        env = gym.make("pliant/TrunkSpaceDebris-v0", **{**kwargs, "success": "catch"})
        result = check_folder(env, folder)
        path = folder / "catch_check.json"
        tmp = path.with_suffix(".tmp")
        tmp.write_text(json.dumps(result, indent=1))
        os.replace(tmp, path)
        print(folder, {k: v for k, v in result.items() if k != "programs"})


if __name__ == "__main__":
    main()
