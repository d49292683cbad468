"""Worker processes that end with the process that started them.

A pool's workers outlive a parent killed by a signal (SIGKILL, an out-of-memory kill, a
closed terminal): nothing tells them, and each keeps its memory (hundreds of MB for a meshed
robot) until its task ends, minutes later. Each worker watches its parent instead: a daemon
thread polls :func:`os.getppid`, which changes when the parent dies (the orphan is adopted by
init or a subreaper), and ends the worker at once. Polling, not Linux's PR_SET_PDEATHSIG,
which fires when the parent *thread* that started the worker ends, and pools start workers
from helper threads.

A Ray actor is not a child of the driver that created it (the node's raylet starts it), so it
watches the driver by identity instead: :func:`driver_identity` in the driver, passed to the
actor, and :func:`exit_with_process` there. Ray also ends a dead driver's actors itself (its
job is marked finished); the watchdog makes that independent of the cluster's bookkeeping,
covers detached actors, and ends them even if the cluster cannot tell.

:func:`run_jobs` runs independent jobs (the chunks of a long collection) on such workers, or
as Ray tasks, and hands back each result as it comes.
"""

from __future__ import annotations

import multiprocessing
import os
import pickle
import socket
import threading
import time
from collections.abc import Callable, Hashable, Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pliant.errors import MissingDependencyError, WorkerError

ORPHAN_EXIT = 70  # exit status of a worker whose parent died (EX_SOFTWARE)
_watched: set[ProcessIdentity] = set()  # one watchdog per process watched (reused Tune actors)


def _watch(alive: Callable[[], bool], interval: float) -> None:
    def watch() -> None:
        while alive():
            time.sleep(interval)
        os._exit(ORPHAN_EXIT)  # no cleanup: the process that would read the results is gone

    threading.Thread(target=watch, name="parent-watchdog", daemon=True).start()


def exit_with_parent(parent: int, interval: float = 0.5) -> None:
    """End this process within `interval` seconds once `parent` is no longer its parent.

    Use as a pool's initializer: ``ProcessPoolExecutor(initializer=exit_with_parent,
    initargs=(os.getpid(),))`` (an environment worker calls it first thing; a Ray actor uses
    :func:`exit_with_process`).
    """
    _watch(lambda: os.getppid() == parent, interval)


@dataclass(frozen=True)
class ProcessIdentity:
    """A process told apart from a later one that reuses its id: the machine (its boot id, or
    its host name where there is no /proc), the pid and the start time (clock ticks since
    boot; None where there is no /proc)."""

    machine: str
    pid: int
    start: int | None


def _machine() -> str:
    try:
        return Path("/proc/sys/kernel/random/boot_id").read_text().strip()
    except OSError:
        return socket.gethostname()


def _start_time(pid: int) -> tuple[int, str] | None:
    """(start time, state) of `pid` from /proc, or None where it cannot be read."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except (OSError, IndexError):
        return None
    return int(fields[19]), fields[0]  # stat fields 22 (starttime) and 3 (state)


def driver_identity(pid: int | None = None) -> ProcessIdentity:
    """The identity of process `pid` (this one by default), to hand to a worker that is not
    its child (a Ray actor) so that it can :func:`exit_with_process` it."""
    pid = os.getpid() if pid is None else pid
    found = _start_time(pid)
    return ProcessIdentity(_machine(), pid, None if found is None else found[0])


def is_running(identity: ProcessIdentity) -> bool:
    """Whether the process `identity` (on this machine) still runs."""
    if identity.start is not None:
        found = _start_time(identity.pid)
        # gone, a zombie (killed, not yet reaped), or another process with a reused id
        return found is not None and found[1] != "Z" and found[0] == identity.start
    try:
        os.kill(identity.pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # it exists, under another user
        return True
    return True


def exit_with_process(identity: ProcessIdentity, interval: float = 0.5) -> bool:
    """End this process within `interval` seconds once the process `identity` has ended.

    A process on another machine cannot be watched: returns False and watches nothing (Ray
    ends a dead driver's actors on other nodes through its own job bookkeeping). Returns True
    when the watchdog runs.
    """
    if identity.machine != _machine():
        return False
    if identity not in _watched:
        _watched.add(identity)
        _watch(lambda: is_running(identity), interval)
    return True


def run_jobs(
    function: Callable[..., Any],
    jobs: Sequence[tuple[Hashable, tuple]],
    *,
    workers: int | None = None,
    ray_address: str | None = None,
    what: str = "chunk",
) -> Iterator[tuple[Hashable, Any]]:
    """(key, function(*args)) for each (key, args) of `jobs`, in the order they finish.

    In this process when `workers` is 1; on `workers` local processes (default: one per CPU)
    started by spawn, not fork (gmsh, numba's OpenMP and the parent's BLAS threads must not be
    inherited), each ending with this process (:func:`exit_with_parent`; killed, it would
    leave them computing for minutes); or as Ray tasks on `ray_address` ("auto", "local",
    "ray://host:port"), at most `workers` at a time when it is given. `function` and the
    arguments must pickle. A local worker that dies raises WorkerError naming the `what` it
    was running; the results already handed back are the caller's to keep.
    """
    if ray_address is not None:
        yield from _ray_jobs(function, jobs, ray_address, workers)
        return
    workers = min(workers or os.cpu_count() or 1, max(1, len(jobs)))
    if workers == 1:
        for key, args in jobs:
            yield key, function(*args)
        return
    pool = ProcessPoolExecutor(
        workers,
        mp_context=multiprocessing.get_context("spawn"),
        initializer=exit_with_parent,
        initargs=(os.getpid(),),
    )
    try:
        futures = {pool.submit(function, *args): key for key, args in jobs}
        for future in as_completed(futures):
            try:
                result = future.result()
            except BrokenProcessPool as exc:
                raise WorkerError(
                    f"a worker process died while running {what} {futures[future]} (killed, or"
                    f" out of memory?); the {what}s finished are saved: rerun the same command"
                    " to resume (fewer --workers if memory is short)"
                ) from exc
            yield futures[future], result
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


def _ray_jobs(
    function: Callable[..., Any],
    jobs: Sequence[tuple[Hashable, tuple]],
    address: str,
    workers: int | None,
) -> Iterator[tuple[Hashable, Any]]:
    try:
        import ray
    except ImportError as exc:
        raise MissingDependencyError(
            "running on Ray needs the 'ray' package: pip install 'pliant[ray]'"
        ) from exc
    ray.init(
        address=address, ignore_reinit_error=True, include_dashboard=False, log_to_driver=False
    )
    # The arguments travel pickled: Ray would hand their NumPy arrays to the task read-only
    # (views of its object store), and a model's work arrays are written in place.
    remote = ray.remote(_unpickled_call)
    waiting = list(jobs)
    pending: dict = {}
    try:
        while waiting or pending:
            while waiting and (workers is None or len(pending) < workers):
                key, args = waiting.pop(0)
                pending[remote.remote(function, ray.cloudpickle.dumps(args))] = key
            (ready,), _ = ray.wait(list(pending), num_returns=1)
            yield pending.pop(ready), ray.get(ready)
    finally:
        for ref in pending:
            ray.cancel(ref)


def _unpickled_call(function: Callable[..., Any], arguments: bytes) -> Any:
    return function(*pickle.loads(arguments))
