"""Where a step's time goes, and how far the default step is from the exact one.

Two measurements `pliant bench` adds to each scene (#24):

* :func:`step_breakdown`: milliseconds per step spent in the compiled and library parts of the
  step (internal forces and K v, assembly of the tangent, CHOLMOD's factorisation, the linear
  solves, the constraint and contact work), read from a profiled run, and the rest (the step's
  Python and small numpy operations) as the unprofiled time per step minus those parts. The
  parts are single calls into compiled code, on which the profiler's per-call cost is small;
  the Python rest is what is left of a clean timing, not the profiler's own (inflated) figure.
* :func:`default_error`: the default (``"lagged"``) trajectory against the exact one (every step
  on the current tangent: ``"fresh"``, or ``"pcg"`` to 1e-10 where a factorisation per step
  would take minutes) over the same steps from rest: the largest node distance at the end and
  over the run, beside the largest motion of a node, so that the error reads as a fraction of
  the motion (#24 asks for at most 1 %).
"""

from __future__ import annotations

import cProfile
import pstats
import time
from collections.abc import Callable

import numpy as np

from pliant.solvers import BatchedImplicitEuler, ImplicitEuler

# Profiled functions (file suffix, function name) of each part. A part's time is the
# cumulative time of its functions, which do not call one another.
PARTS: dict[str, tuple[tuple[str, str], ...]] = {
    "forces": (("pliant/fem/body.py", "linearise"),),
    "assembly": (("pliant/solvers/system.py", "_assemble"),),
    "factorisation": (
        ("pliant/solvers/cholmod.py", "factorize"),
        ("pliant/solvers/linear.py", "factorize"),
        ("pliant/solvers/system.py", "_wait"),  # a background factorisation waited for
    ),
    "solves": (
        ("pliant/solvers/cholmod.py", "solve"),
        ("pliant/solvers/linear.py", "solve"),
        ("pliant/solvers/linear.py", "block_pcg"),
    ),
    "constraints": (
        ("pliant/constraints/control.py", "constraint_forces"),
        ("pliant/constraints/contact.py", "constraint"),
        ("pliant/model.py", "constraint_space"),
    ),
}


def _cumulative(stats: pstats.Stats) -> dict[str, float]:
    """Seconds of each part in a profile (`stats.stats`: (file, line, name) -> timings)."""
    out = dict.fromkeys(PARTS, 0.0)
    for (filename, _line, name), (_cc, _nc, _tt, cumulative, _callers) in stats.stats.items():
        path = filename.replace("\\", "/")
        for part, functions in PARTS.items():
            if any(path.endswith(f) and name == n for f, n in functions):
                out[part] += cumulative
    return out


def step_breakdown(
    make_solver: Callable[[], object],
    state,
    control: Callable[[object], object],
    steps: int,
    warmup: int,
) -> dict[str, float]:
    """Milliseconds per step of each part of :data:`PARTS`, "rest" and "total" (unprofiled),
    over `steps` steps after `warmup`; the factorisations per step too."""
    solver = make_solver()
    for _ in range(warmup):
        state = solver.step(state, control(state))
    start = state.copy()
    s, t0 = start.copy(), time.perf_counter()
    f0 = solver.system.factorisations
    for _ in range(steps):
        s = solver.step(s, control(s))
    total = (time.perf_counter() - t0) / steps
    factorisations = (solver.system.factorisations - f0) / steps
    # The same steps again, profiled (the solver is rewound to the same state: the lagged
    # factorisation may differ in age, which the factorisations per step of both runs show).
    solver = make_solver()
    s = start.copy()
    for _ in range(2):  # compile nothing in the profiled window
        s = solver.step(s, control(s))
    s = start.copy()
    profile = cProfile.Profile()
    profile.enable()
    for _ in range(steps):
        s = solver.step(s, control(s))
    profile.disable()
    parts = {k: 1e3 * v / steps for k, v in _cumulative(pstats.Stats(profile)).items()}
    out = {"total": 1e3 * total, **parts}
    out["rest"] = max(0.0, out["total"] - sum(parts.values()))
    out["factorisations_per_step"] = factorisations
    return out


def default_error(
    model,
    control: Callable[[object], object],
    *,
    steps: int = 100,
    dt: float = 0.01,
    exact: str = "fresh",
) -> dict[str, float]:
    """The default step's departure from the exact one over `steps` steps from rest (mm)."""

    def trajectory(tangent: str) -> np.ndarray:
        solver = ImplicitEuler(model, dt, tangent=tangent)
        s = model.rest_state()
        out = []
        for _ in range(steps):
            s = solver.step(s, control(s))
            out.append(s.positions.copy())
        return np.array(out)

    reference = trajectory(exact)
    default = trajectory("lagged")
    distance = np.linalg.norm(default - reference, axis=2)
    motion = np.linalg.norm(reference - model.rest_state().positions[None], axis=2).max()
    return {
        "exact_policy": exact,
        "steps": steps,
        "error_end_mm": float(distance[-1].max()),
        "error_max_mm": float(distance.max()),
        "motion_max_mm": float(motion),
        "error_end_percent_of_motion": float(100.0 * distance[-1].max() / max(motion, 1e-300)),
    }


def batch_throughput(
    model, commands, counts, *, steps: int = 30, warmup: int = 5, threads: int | None = None
) -> list[dict[str, float]]:
    """Copy-steps per second of :class:`pliant.solvers.BatchedImplicitEuler` for each copy
    count N, beside N single solvers stepped one after the other in a loop (same commands
    `commands`, (n_actuators,) or None, for every copy); both from rest after `warmup`
    steps."""
    out = []
    for n in counts:
        singles = [ImplicitEuler(model, 0.01) for _ in range(n)]
        states = [model.rest_state() for _ in range(n)]
        for k in range(warmup + steps):
            if k == warmup:
                t0 = time.perf_counter()
            states = [s.step(x, commands) for s, x in zip(singles, states, strict=True)]
        single = n * steps / (time.perf_counter() - t0)
        control = None if commands is None else np.tile(commands, (n, 1))
        with BatchedImplicitEuler(model, n, 0.01, threads=threads) as batch:
            states = batch.rest_states()
            for k in range(warmup + steps):
                if k == warmup:
                    t0 = time.perf_counter()
                states = batch.step(states, control)
            batched = n * steps / (time.perf_counter() - t0)
            used = batch.threads
        out.append(
            {
                "copies": n,
                "threads": used,
                "single_loop": single,
                "batched": batched,
                "gain": batched / single,
            }
        )
    return out
