"""Worker processes that end with the process that started them.

A pool's workers outlive a parent killed by a signal (SIGKILL, an out-of-memory kill, a
closed terminal): nothing tells them, and each keeps its memory (hundreds of MB for a meshed
robot) until its task ends, minutes later. Each worker watches its parent instead: a daemon
thread polls :func:`os.getppid`, which changes when the parent dies (the orphan is adopted by
init or a subreaper), and ends the worker at once. Polling, not Linux's PR_SET_PDEATHSIG,
which fires when the parent *thread* that started the worker ends, and pools start workers
from helper threads.
"""

from __future__ import annotations

import os
import threading
import time

ORPHAN_EXIT = 70  # exit status of a worker whose parent died (EX_SOFTWARE)


def exit_with_parent(parent: int, interval: float = 0.5) -> None:
    """End this process within `interval` seconds once `parent` is no longer its parent.

    Use as a pool's initializer: ``ProcessPoolExecutor(initializer=exit_with_parent,
    initargs=(os.getpid(),))`` (a Ray actor or an environment worker calls it first thing).
    """

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(interval)
        os._exit(ORPHAN_EXIT)  # no cleanup: the parent that would read the results is gone

    threading.Thread(target=watch, name="parent-watchdog", daemon=True).start()
