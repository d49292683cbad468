"""Workers that die (issue 64): a local worker of the reduction's snapshot collection killed
(SIGKILL) mid-case ends the run with a WorkerError naming the case, within a time limit (the
collection runs in a child process with a timeout, so that a hang fails the test rather than
the run); the cases finished are kept and the same call resumes to the file of a collection
never interrupted. (The condensed collection's pool, the RL environment workers and Ray's
actors are tested in test_faults.py and tests/learn/test_learn.py.)"""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("h5py")

import fault_injection  # noqa: E402  (tests/reliability is on the path, as for test_faults)

ROOT = Path(__file__).resolve().parent
#: this tree's Pliant (not another checkout's installed one) and fault_injection
PATH = os.pathsep.join([str(ROOT.parents[1]), str(ROOT), os.environ.get("PYTHONPATH", "")])

SCRIPT = """
import sys
import numpy as np
from fault_injection import DyingCommands
from pliant.errors import WorkerError
from pliant import robots
from pliant.reduction import snapshots
from pliant.reduction.pipeline import RampedCommands
from pliant.reduction.snapshots import LoadCase

model = robots.build("finger")
dying = sys.argv[2] == "die"
cases = [
    LoadCase("steady", RampedCommands([np.array([2.0, 1.0])] * 2, 0.05), 0.1),
    LoadCase("second", DyingCommands(2.0, 0.05 if dying else 1.0), 0.1),
]
try:
    snapshots.collect(model, cases, sys.argv[1], every=2, workers=2)
except WorkerError as exc:
    print("WorkerError:", exc)
    sys.exit(3)
"""


def _collect(path: Path, mode: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-c", textwrap.dedent(SCRIPT), str(path), mode],
        cwd=ROOT,
        env={**os.environ, "PYTHONPATH": PATH},
        capture_output=True,
        text=True,
        timeout=300,  # a hung pool fails here
    )


def test_a_dead_snapshot_worker_stops_the_run_with_its_cause_and_it_resumes(tmp_path):
    from pliant.reduction import snapshots

    path = tmp_path / "s.h5"
    dead = _collect(path, "die")
    assert dead.returncode == 3, dead.stdout + dead.stderr
    assert "load case" in dead.stdout and "second" in dead.stdout, dead.stdout
    assert set(snapshots.load(path)) <= {"steady"}  # the file is whole, the dead case absent
    # The same call resumes (here in this process: serial and parallel collections give the
    # same bits) to the file of a collection never interrupted.
    from pliant import robots
    from pliant.reduction.pipeline import RampedCommands
    from pliant.reduction.snapshots import LoadCase

    model = robots.build("finger")
    cases = [
        LoadCase("steady", RampedCommands([np.array([2.0, 1.0])] * 2, 0.05), 0.1),
        LoadCase("second", fault_injection.DyingCommands(2.0, 1.0), 0.1),
    ]
    snapshots.collect(model, cases, path, every=2)
    snapshots.collect(model, cases, tmp_path / "once.h5", every=2)
    a, b = snapshots.load(path), snapshots.load(tmp_path / "once.h5")
    assert sorted(a) == sorted(b) == ["second", "steady"]
    for name in a:
        for u, v in zip(a[name], b[name], strict=True):
            assert u.tobytes() == v.tobytes(), name
