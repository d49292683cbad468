"""What a rollout gradient costs beside the rollout, and the memory of a 1000-step Trunk.

    python experiments/diff/cost.py [--trunk-steps 1000] [--repeats 3]

For the coarse Soft Finger (1610 tetrahedra, 50 steps), the Diamond (4046, 30 steps) and the
Trunk (default mesh, `--trunk-steps` steps, two cables ramped to 10 and 5 mm over the first
30 %): the forward rollout's wall time and the gradient's, keeping every state and with
checkpoints every ceil(sqrt(T)) steps (:func:`pliant.diff.cost.gradient_cost`), the states held
at once, and for the Trunk the peak of Python-allocated memory. The Finger and the Diamond are
timed `--repeats` times, interleaved in this one process (medians; the ratios are what travel
to another machine), the Trunk once. Writes experiments/results/diff/cost.json. Timings are
wall-clock on the shared 2-core machine, under other jobs' load (the host's load average is
recorded).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from pliant import robots
from pliant.bench.host import host
from pliant.diff.cost import gradient_cost
from pliant.files import write_json

ROOT = Path(__file__).resolve().parents[2]
OUT = ROOT / "experiments" / "results" / "diff" / "cost.json"
DT = 0.01


def measure(name, model, commands, n_steps, *, memory: bool = False, repeats: int = 1) -> dict:
    row = gradient_cost(model, commands, n_steps, dt=DT, memory=memory, repeats=repeats)
    print(name, json.dumps(row), flush=True)
    return row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trunk-steps", type=int, default=1000)
    parser.add_argument("--repeats", type=int, default=3, help="Finger's and Diamond's")
    args = parser.parse_args()
    finger, diamond = robots.soft_finger(), robots.diamond()
    out = {
        "finger": measure("finger", finger, np.array([8.0, 0.0]), 50, repeats=args.repeats),
        "diamond": measure(
            "diamond", diamond, np.array([10.0, 0.0, 5.0, 0.0]), 30, repeats=args.repeats
        ),
        "trunk": measure(
            "trunk",
            robots.trunk(),
            np.array([10.0, 0, 0, 0, 0, 0, 5.0, 0]),
            args.trunk_steps,
            memory=True,
        ),
    }
    out["host"] = host()
    write_json(OUT, out)


if __name__ == "__main__":
    main()
