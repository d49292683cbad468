"""Many ``pliant proxy transfer`` runs at a time, each in a child process on one thread (the
Multigait transfer studies: experiments/proxy/corrector.py, prior.py, twin.py)."""

from __future__ import annotations

import os
import subprocess
from pathlib import Path


def run_jobs(jobs: list[list[str]], workers: int, env: dict) -> None:
    """Run the commands `workers` at a time (their output discarded: each writes its JSON)."""
    running: list[subprocess.Popen] = []
    for command in jobs:
        while len(running) >= workers:
            running.pop(0).wait()
        print(" ".join(command), flush=True)
        running.append(
            subprocess.Popen(command, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        )
    for process in running:
        process.wait()


def run_transfers(cases, workers: int) -> None:
    """Each (options, folder) of `cases` as ``pliant proxy transfer multigait OPTIONS --out
    FOLDER``, `workers` at a time on one thread each; a folder whose JSON is there is not run
    again (a study resumes)."""
    env = {**os.environ, "OMP_NUM_THREADS": "1", "NUMBA_NUM_THREADS": "1"}
    env["OPENBLAS_NUM_THREADS"] = "1"
    jobs = [
        ["pliant", "proxy", "transfer", "multigait", *options, "--out", str(folder)]
        for options, folder in cases
        if not (Path(folder) / "multigait_transfer.json").exists()
    ]
    run_jobs(jobs, workers, env)
