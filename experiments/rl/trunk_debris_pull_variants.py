"""TrunkSpaceDebris: does a closed-loop whole-arm pull catch more than the plain one? (issue
#16: the expert's ceiling bounds what cloning it gives PPO.)

    PYTHONPATH=. python experiments/rl/trunk_debris_pull_variants.py [--tests 40]

On the catchable variant (trunk_debris_ppo.py's VARIANTS, cable increments, the catch test),
the test placements of trunk_debris_ppo.py (seeds 30000 on), each program below plays every
placement; the long cable facing the cube is pulled as the expert pulls it
(``pliant.envs.trunk_space_debris.pull_weights``), and the programs differ in what they do
once the trunk touches the cube (``info`` of the previous step: faces pressed, opposite
faces). Writes experiments/results/rl/trunk_debris_pull_variants.json (catch rates overall
and per cube size), about 45 s a program on one core.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from experiments.rl.trunk_debris_ppo import VARIANTS
from pliant.condensed.dataset import atomic_write
from pliant.envs import make
from pliant.envs.trunk_space_debris import pull_weights

OUT = Path("experiments/results/rl/trunk_debris_pull_variants.json")
PROGRAMS = {
    "full": "the expert: the long cable pulled at the full rate to its end and held",
    "hold_at_opposite": "the same, the cables held once two opposite faces are pressed",
    "quarter_at_opposite": "the same, a quarter of the rate once opposite faces are pressed",
    "half_at_touch": "half the rate once any face is pressed",
    "hold_at_two_faces": "the cables held once two faces are pressed",
    "short_at_touch": "the short cable on the cube's side added once any face is pressed",
    "long_and_short": "the short cable on the cube's side pulled at half the rate throughout",
}


def program(name: str, weights: np.ndarray):
    """info of the previous step -> the step's cable increments (in [-1, 1] of the rate)."""
    short = np.r_[np.zeros(4), weights[:4]]  # cables 4-7: the short ones, same azimuths
    state = {"after": False}

    def act(info: dict) -> np.ndarray:
        if name in ("hold_at_opposite", "quarter_at_opposite"):
            state["after"] |= bool(info.get("opposite_faces"))
        elif name in ("half_at_touch", "short_at_touch"):
            state["after"] |= info.get("faces", 0) >= 1
        elif name == "hold_at_two_faces":
            state["after"] |= info.get("faces", 0) >= 2
        after = state["after"]
        if name == "full":
            return weights
        if name in ("hold_at_opposite", "hold_at_two_faces"):
            return weights * (not after)
        if name == "quarter_at_opposite":
            return weights * (0.25 if after else 1.0)
        if name == "half_at_touch":
            return weights * (0.5 if after else 1.0)
        if name == "short_at_touch":
            return weights + short if after else weights
        return weights + 0.5 * short  # long_and_short

    return act


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tests", type=int, default=40)
    args = parser.parse_args()
    if args.tests < 1:
        parser.error("--tests must be >= 1")
    env = make("pliant/TrunkSpaceDebris-v0", **VARIANTS["catchable"], continuous_mode="increment")
    report = {
        "command": "PYTHONPATH=. python experiments/rl/trunk_debris_pull_variants.py"
        f" --tests {args.tests}",
        "variant": VARIANTS["catchable"],
        "seeds": [30_000, 30_000 + args.tests - 1],
        "programs": {},
    }
    for name, what in PROGRAMS.items():
        catches = []
        for k in range(args.tests):
            env.reset(seed=30_000 + k)
            e = env.unwrapped
            act, info = program(name, pull_weights(e.cube())), {}
            for _ in range(e.horizon):
                action = np.clip(act(info), -1.0, 1.0).astype(np.float32)
                _, _, terminated, truncated, info = env.step(action)
                if terminated or truncated:
                    break
            catches.append((float(e.cube_size), bool(info["is_success"])))
        sizes = sorted({s for s, _ in catches})
        report["programs"][name] = {
            "what": what,
            "catch_rate": float(np.mean([c for _, c in catches])),
            "by_cube_size": {
                str(s): {
                    "tests": sum(1 for t, _ in catches if t == s),
                    "catch_rate": float(np.mean([c for t, c in catches if t == s])),
                }
                for s in sizes
            },
        }
        print(name, report["programs"][name]["catch_rate"], flush=True)
        atomic_write(OUT, lambda tmp: Path(tmp).write_text(json.dumps(report, indent=1)))


if __name__ == "__main__":
    main()
