"""Snapshot collection of the Multigait's training load cases, serial against local workers.

    OPENBLAS_NUM_THREADS=1 python experiments/reduction/parallel_snapshots.py [--workers 2]

The default mesh and load cases (pliant.reduction.multigait_cases: the hand-gait cycle, each
symmetric group alone, three random action sequences; 1980 full steps of 0.01 s, positions
every 5), collected into fresh HDF5 files in this process and on `--workers` spawned
processes; wall clock of each (the model built beforehand, so the workers' start, import and
model transfer are counted, the meshing is not), the CPU time of this process and its
children, and whether the two files hold the same snapshots bit for bit.
Writes experiments/results/reduction/parallel_snapshots.json.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import tempfile
import time
from pathlib import Path

import numpy as np

from pliant.reduction import snapshots
from pliant.reduction.pipeline import multigait_cases
from pliant.robots.multigait import multigait

OUT = Path(__file__).parents[1] / "results" / "reduction" / "parallel_snapshots.json"


def cpu_seconds() -> float:
    """CPU time of this process and of its finished children."""
    own = resource.getrusage(resource.RUSAGE_SELF)
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    model = multigait()
    cases = multigait_cases()
    runs, load = {}, os.getloadavg()
    with tempfile.TemporaryDirectory() as work:
        for label, workers in (("serial", 1), (f"{args.workers} workers", args.workers)):
            path = Path(work) / f"{workers}.h5"
            clock, cpu = time.perf_counter(), cpu_seconds()
            snapshots.collect(model, cases, path, workers=workers)
            runs[label] = {
                "wall_s": time.perf_counter() - clock,
                "cpu_s": cpu_seconds() - cpu,
                "snapshots": snapshots.load(path, model),
            }
            print(label, f"{runs[label]['wall_s']:.1f} s", flush=True)
    serial, parallel = (runs[k].pop("snapshots") for k in list(runs))
    same = serial.keys() == parallel.keys() and all(
        np.array_equal(serial[k][i], parallel[k][i]) for k in serial for i in (0, 1)
    )
    result = {
        "robot": "multigait (default mesh)",
        "cases": [c.name for c in cases],
        "full_steps": sum(c.steps(0.01) for c in cases),
        "cpus": os.cpu_count(),
        "load_average_before_after": [load, os.getloadavg()],
        "runs": runs,
        "speed_up": runs["serial"]["wall_s"] / runs[f"{args.workers} workers"]["wall_s"],
        "bitwise_equal": bool(same),
    }
    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.write_text(json.dumps(result, indent=1))
    print(json.dumps(result, indent=1))


if __name__ == "__main__":
    main()
