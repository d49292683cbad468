"""Many copies of one model stepped by one call (N environments, one Python call per step).

:class:`BatchedImplicitEuler` holds N copies of a model, each with its own :class:`ImplicitEuler`
(its own factorisation, lag and caches), and advances all of them with ``step(states,
controls)``. Each copy's step is exactly the single step, so a batch of N equals N single
steps bit for bit (tested), whatever the threads do.

The copies run on a pool of threads (one per core by default). What runs in parallel is what
releases the GIL: the compiled kernels (internal forces and K v, assembly, the gathers) and
CHOLMOD's factorisations and solves; the step's Python runs one copy at a time. On a small
body, where a single step is mostly Python, the gain is the overlap of one copy's kernels and
factorisation with another's Python; on a large body, the kernels of two copies on two cores.
`pliant bench` reports the throughput (copy-steps per second) against N single steps.

Copies are deep copies of the model given, so that no two threads share a constraint's or a
load's working arrays, and states of the model given are states of every copy.
"""

from __future__ import annotations

import copy
import os
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from pliant.errors import ModelError, PliantError, SolverError
from pliant.model import Model, State
from pliant.solvers.base import StepReport
from pliant.solvers.implicit_euler import ImplicitEuler

#: below this many elements a batch runs its copies on one thread (see `threads`).
SMALL_BODY = 1000


class BatchedImplicitEuler:
    """N copies of `model` advanced together by :meth:`step`.

    Args:
        model: the robot (deep-copied `copies` times; it is not stepped itself).
        copies: N, at least 1.
        dt: time step of every copy.
        threads: worker threads (default: the machine's cores, at most N, for a body of
            SMALL_BODY elements or more; one below, where a step is mostly Python and threads
            only add switching: `pliant bench` measured N = 8 on a 240-tet cantilever at 0.65x
            the single loop on two threads, and the 1972-tet Trunk with cables at 1.34x).
        **options: :class:`ImplicitEuler`'s keyword options (tangent policy, ...).
    """

    def __init__(
        self,
        model: Model,
        copies: int,
        dt: float = 0.01,
        *,
        threads: int | None = None,
        **options,
    ) -> None:
        if not isinstance(model, Model):
            raise ModelError(f"a batch steps copies of a pliant Model, got {type(model).__name__}")
        if isinstance(copies, bool) or not isinstance(copies, (int, np.integer)) or copies < 1:
            raise SolverError(f"copies must be an integer >= 1, got {copies!r}")
        if threads is None:
            small = model.body.n_elements < SMALL_BODY
            threads = 1 if small else min(int(copies), os.cpu_count() or 1)
        if isinstance(threads, bool) or not isinstance(threads, (int, np.integer)) or threads < 1:
            raise SolverError(f"threads must be an integer >= 1, got {threads!r}")
        self.model = model
        self.models = [copy.deepcopy(model) for _ in range(int(copies))]
        self.solvers = [ImplicitEuler(m, dt, **options) for m in self.models]
        for solver in self.solvers:
            # The batch is the concurrency: a copy's factorisation runs on its own thread
            # rather than queueing on the single background one all solvers share.
            solver._background = False
        self.dt = self.solvers[0].dt
        self.threads = int(threads)
        self._pool = (
            ThreadPoolExecutor(self.threads, thread_name_prefix="pliant-batch")
            if self.threads > 1
            else None
        )

    @property
    def copies(self) -> int:
        return len(self.solvers)

    @property
    def last_reports(self) -> list[StepReport]:
        return [s.last_report for s in self.solvers]

    def rest_states(self) -> list[State]:
        """Every copy at rest."""
        return [m.rest_state() for m in self.models]

    def step(
        self, states: Sequence[State], controls=None, *, errors: str = "raise"
    ) -> list[State | PliantError]:
        """Advance copy i from `states[i]` under `controls[i]`.

        `controls`: None (no actuation), an (N, n_actuators) array of commands (one row per
        copy), or a sequence of N controls, each what :meth:`ImplicitEuler.step` accepts.
        `errors`: "raise" raises the first failing copy's error (after every copy has run),
        its message naming the copy; "return" puts each failing copy's error in its place
        in the list, so that the other copies go on (an RL batch resets only those).
        """
        if errors not in ("raise", "return"):
            raise SolverError(f"errors must be 'raise' or 'return', got {errors!r}")
        n = self.copies
        if isinstance(states, State) or len(states) != n:
            raise SolverError(f"step needs a sequence of {n} states (one per copy)")
        per_copy = self._controls(controls)
        if self._pool is None:
            results = [self._one(i, states[i], per_copy[i]) for i in range(n)]
        else:
            results = list(self._pool.map(self._one, range(n), states, per_copy))
        if errors == "raise":
            for i, r in enumerate(results):
                if isinstance(r, PliantError):
                    r.args = (f"copy {i}: {r.args[0] if r.args else r}", *r.args[1:])
                    raise r
        return results

    def _controls(self, controls) -> list:
        n, m = self.copies, self.model.n_actuators
        if controls is None:
            return [None] * n
        if isinstance(controls, np.ndarray) and controls.dtype != object:
            if controls.shape != (n, m):
                raise SolverError(
                    f"batched commands must have shape ({n}, {m}) (copies, actuators),"
                    f" got {controls.shape}"
                )
            return list(controls)
        controls = list(controls)
        if len(controls) != n:
            raise SolverError(f"give one control per copy: {n}, got {len(controls)}")
        return controls

    def _one(self, i: int, state: State, control) -> State | PliantError:
        try:
            return self.solvers[i].step(state, control)
        except PliantError as exc:
            return exc

    def close(self) -> None:
        """Stop the worker threads (also done when the batch is garbage-collected)."""
        if self._pool is not None:
            self._pool.shutdown(wait=True)
            self._pool = None

    def __enter__(self) -> BatchedImplicitEuler:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __del__(self) -> None:
        pool = getattr(self, "_pool", None)
        if pool is not None:
            pool.shutdown(wait=False)
