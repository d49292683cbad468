"""Faulty stand-ins for a collection worker's task, for tests/reliability/test_faults.py. They
live in an importable module (not a test file) so that spawned worker processes can unpickle
them."""

from __future__ import annotations

import os
import signal
import time

import numpy as np

from pliant.condensed.collect import solve_chunk

DIE_AT_ENV = "PLIANT_FAULT_DIE_AT"  # "first sample" of the chunk whose worker is killed
SLOW_ENV = "PLIANT_FAULT_SLOW"  # seconds each chunk takes at least


def dying_solve_chunk(plan, points: np.ndarray):
    """solve_chunk, but the worker is killed (SIGKILL, as by the out-of-memory killer) on the
    chunk whose first point equals the plan's point named by DIE_AT_ENV."""
    target = plan.points()["train"][int(os.environ[DIE_AT_ENV])]
    if np.array_equal(np.atleast_2d(points)[0], target):
        os.kill(os.getpid(), signal.SIGKILL)
    return solve_chunk(plan, points)


def slow_solve_chunk(plan, points: np.ndarray):
    """solve_chunk taking at least SLOW_ENV seconds: a long job to kill the parent of."""
    time.sleep(float(os.environ.get(SLOW_ENV, "1")))
    return solve_chunk(plan, points)


class DyingCommands:
    """Load-case commands (pliant.reduction.snapshots) that kill the process running them
    (SIGKILL) at `time` seconds: a reduction worker that dies mid-case."""

    def __init__(self, level: float, time: float) -> None:
        self.level, self.time = level, time

    def __call__(self, t: float) -> np.ndarray:
        if t >= self.time:
            os.kill(os.getpid(), signal.SIGKILL)
        return np.array([self.level, 0.5 * self.level]) * min(t / 0.05, 1.0)


#: The damages tests/reliability gives a file Pliant reads back.
DAMAGE = ("truncated", "empty", "random bytes")


def damage(path, how: str) -> None:
    """Truncate `path` to half, empty it, or overwrite it with random bytes (`how`)."""
    data = path.read_bytes()
    if how == "truncated":
        path.write_bytes(data[: len(data) // 2])
    elif how == "empty":
        path.write_bytes(b"")
    else:
        path.write_bytes(np.random.default_rng(0).bytes(max(len(data), 64)))
