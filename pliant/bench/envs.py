"""Environment speed: environment steps and simulation steps per second, and the real-time
factor RTF = simulated time / wall time (thesis Eq. 3.1), at several time steps.

An environment step lasts the same simulated time at every dt (the sub-steps scale as 1/dt), so
that the figures compare the same task. Actions are random (seeded) and the episode restarts
when it ends; the first step (compilation, first factorisation) is not timed.
"""

from __future__ import annotations

import functools
import importlib
import json
import statistics
import sys
import threading
import time
import warnings
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
from rich import box
from rich.console import Console
from rich.table import Table

from pliant.envs import ENVS, make, make_subproc_vec_env
from pliant.errors import UnknownRobotError
from pliant.viz.video import atomic_path


@dataclass
class EnvSpeed:
    env: str
    dt: float
    substeps: int
    env_steps: int
    env_steps_per_s: float
    sim_steps_per_s: float
    real_time_factor: float
    stable: bool
    note: str = ""


# ------------------------------------------------------------------ where a step's time goes
#: The parts of an environment step that :func:`profile_env` times: (module, function or
#: Class.method) of each. A part's time is its functions' own time, less that of the parts
#: they call (collision detection inside the contact rows counts as collision), on the
#: stepping thread only (a background factorisation counts where the step waits for it).
ENV_PARTS: dict[str, tuple[tuple[str, str], ...]] = {
    "collision": (
        ("pliant.geometry.collision", "detect"),
        ("pliant.geometry.collision", "collide"),
    ),
    "forces": (
        ("pliant.fem.body", "TetBody.linearise"),
        ("pliant.fem.hexbody", "HexBody.linearise"),
        ("pliant.fem.rod", "RodBody.linearise"),
    ),
    "assembly": (("pliant.solvers.system", "LinearisedSystem._assemble"),),
    "factorisation": (
        ("pliant.solvers.cholmod", "CholmodCholesky.factorize"),
        ("pliant.solvers.linear", "CholespyCholesky.factorize"),
        ("pliant.solvers.system", "LinearisedSystem._wait"),
    ),
    "solves": (
        ("pliant.solvers.cholmod", "CholmodCholesky.solve"),
        ("pliant.solvers.linear", "CholespyCholesky.solve"),
        ("pliant.solvers.linear", "block_pcg"),
    ),
    "tangent_lag": (
        ("pliant.solvers.system", "LinearisedSystem._turn"),
        ("pliant.fem.kernels", "max_abs_difference"),
    ),
    "compliance": (
        ("pliant.solvers.compliance", "PointRows.condense"),
        ("pliant.solvers.compliance", "PointCompliance.apply"),
        ("pliant.solvers.implicit_euler", "ImplicitEuler._condense"),
        ("pliant.solvers.implicit_euler", "ImplicitEuler._with_points"),
        ("pliant.solvers.implicit_euler", "ImplicitEuler._free_with_points"),
    ),
    "constraint_rows": (
        ("pliant.constraints.contact", "Contacts.constraint"),
        ("pliant.model", "Model.constraint_space"),
    ),
    "constraint_solve": (("pliant.constraints.control", "constraint_forces"),),
}


class _PartClock:
    """Own time of wrapped functions by part, on one thread and while `running`: a call's
    time less that of the wrapped calls it makes (which their parts get)."""

    def __init__(self) -> None:
        self.running = False
        self.seconds: dict[str, float] = {}
        self._stack: list[list[float]] = []
        self._thread = threading.get_ident()
        self._undo: list[Callable[[], None]] = []

    def wrap(self, part: str, function: Callable) -> Callable:
        self.seconds.setdefault(part, 0.0)

        @functools.wraps(function)
        def timed(*args, **kwargs):
            if not self.running or threading.get_ident() != self._thread:
                return function(*args, **kwargs)
            inner = [0.0]
            self._stack.append(inner)
            start = time.perf_counter()
            try:
                return function(*args, **kwargs)
            finally:
                elapsed = time.perf_counter() - start
                self._stack.pop()
                self.seconds[part] += elapsed - inner[0]
                if self._stack:
                    self._stack[-1][0] += elapsed

        return timed

    def patch(self, owner, name: str, part: str) -> None:
        """Time `owner.name` (a class's own method, or an instance's attribute) as `part`."""
        had = name in vars(owner)
        original = getattr(owner, name)
        setattr(owner, name, self.wrap(part, vars(owner)[name] if had else original))
        self._undo.append(
            (lambda: setattr(owner, name, original)) if had else (lambda: delattr(owner, name))
        )

    def patch_function(self, module: str, name: str, part: str) -> None:
        """Time the function `module.name` wherever a Pliant module holds it by that name."""
        original = getattr(importlib.import_module(module), name)
        timed = self.wrap(part, original)
        for loaded in list(sys.modules.values()):
            if getattr(loaded, "__name__", "").startswith("pliant") and (
                vars(loaded).get(name) is original
            ):
                setattr(loaded, name, timed)
                self._undo.append(lambda m=loaded: setattr(m, name, original))

    def restore(self) -> None:
        while self._undo:
            self._undo.pop()()


def _env_at(name: str, dt: float, **kwargs):
    """The environment `name` at time step `dt`, its sub-steps scaled so that an environment
    step lasts its default simulated time; and those sub-steps."""
    spec_env = make(f"pliant/{name}-v0", **kwargs)
    step_time = spec_env.unwrapped.step_time
    spec_env.close()
    substeps = max(1, round(step_time / dt))
    return make(f"pliant/{name}-v0", dt=dt, substeps=substeps, **kwargs), substeps


def _rollout(env, env_steps: int, seed: int, clock: _PartClock | None = None):
    """Time `env_steps` random (seeded) steps after an untimed first one (compilation, first
    factorisation), restarting ended episodes: (steps done, wall seconds, divergence note).
    `clock` runs during the timed steps only."""
    env.action_space.seed(seed)
    diverged = ""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        env.reset(seed=seed)
        env.step(env.action_space.sample())
        wall, done = 0.0, 0
        while done < env_steps:
            action = env.action_space.sample()
            if clock is not None:
                clock.running = True
            start = time.perf_counter()
            _, _, term, trunc, info = env.step(action)
            wall += time.perf_counter() - start
            if clock is not None:
                clock.running = False
            done += 1
            if "diverged" in info:
                diverged = info["diverged"]
                break
            if term or trunc:
                env.reset()
    return done, wall, diverged


def measure_env(
    name: str, dt: float = 0.01, *, env_steps: int = 10, seed: int = 0, **kwargs
) -> EnvSpeed:
    """Time `env_steps` environment steps of `name` at time step `dt` (default settings, or
    `kwargs`)."""
    env, substeps = _env_at(name, dt, **kwargs)
    try:
        done, wall, diverged = _rollout(env, env_steps, seed)
    finally:
        env.close()
    return EnvSpeed(
        env=name,
        dt=dt,
        substeps=substeps,
        env_steps=done,
        env_steps_per_s=done / wall,
        sim_steps_per_s=done * substeps / wall,
        real_time_factor=done * substeps * dt / wall,
        stable=not diverged,
        note=diverged,
    )


def measure_all(
    names: list[str] | None = None,
    dts: tuple[float, ...] = (0.01, 0.02, 0.03),
    *,
    env_steps: int = 10,
    quick: bool = False,
) -> list[dict]:
    """Every environment (or `names`) at every dt; `quick` uses the small test variants."""
    out = []
    for name in names or sorted(ENVS):
        kwargs = dict(ENVS[name].quick) if quick else {}
        kwargs.pop("substeps", None)
        for dt in dts:
            try:
                out.append(asdict(measure_env(name, dt, env_steps=env_steps, **kwargs)))
            except Exception as exc:  # a failure is a result of the benchmark: report it
                out.append({"env": name, "dt": dt, "stable": False, "note": repr(exc)})
    return out


def _check_names(names: list[str] | None) -> None:
    unknown = sorted(set(names or []) - set(ENVS))
    if unknown:
        raise UnknownRobotError(f"unknown environments {unknown}; available: {sorted(ENVS)}")


def _save(rows: list, table: Table, *, quick: bool, out: Path, console: Console) -> list:
    """Print the table, write the rows' JSON to `out`; the rows."""
    console.print(table)
    out.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(out) as tmp:
        tmp.write_text(json.dumps({"environments": rows, "quick": quick}, indent=1))
    console.print(f"saved {out}")
    return rows


def report_envs(names: list[str] | None, *, quick: bool, out: Path, console: Console) -> list:
    """Measure, print a table and write the JSON (`pliant bench --envs`)."""
    _check_names(names)
    rows = measure_all(names, quick=quick)
    table = Table(title="environments (random actions; RTF = simulated / wall time)")
    for col in ("env", "dt", "sub-steps", "env steps/s", "sim steps/s", "RTF", "note"):
        table.add_column(col)
    for r in rows:
        if "env_steps_per_s" not in r:
            table.add_row(r["env"], f"{r['dt']:g}", "", "", "", "", r["note"][:60])
            continue
        table.add_row(
            r["env"],
            f"{r['dt']:g}",
            str(r["substeps"]),
            f"{r['env_steps_per_s']:.2f}",
            f"{r['sim_steps_per_s']:.0f}",
            f"{r['real_time_factor']:.2f}",
            "" if r["stable"] else "diverged",
        )
    return _save(rows, table, quick=quick, out=out, console=console)


def profile_env(
    name: str, dt: float = 0.01, *, env_steps: int = 10, seed: int = 0, **kwargs
) -> dict:
    """Where an environment step's time goes: the share of each part of :data:`ENV_PARTS`,
    of the solver's other work ("solver_other": its Python and small numpy operations), of
    the observation, of the reward (with the info), and of the rest of the step ("glue": the
    action's check, the commands, the sub-step loop, the Gymnasium wrappers), over
    `env_steps` random steps at `dt` (as :func:`measure_env`). Shares (fractions of the
    step) compare across a loaded machine where absolute times do not; the milliseconds and
    the real-time factor are given beside them."""
    env, substeps = _env_at(name, dt, **kwargs)
    base = env.unwrapped
    clock = _PartClock()
    for part in (*ENV_PARTS, "solver_other", "observation", "reward"):
        clock.seconds[part] = 0.0
    try:
        for part, functions in ENV_PARTS.items():
            for module, qualified in functions:
                owner_name, _, attr = qualified.rpartition(".")
                if owner_name:
                    owner = getattr(importlib.import_module(module), owner_name)
                    clock.patch(owner, attr, part)
                else:
                    clock.patch_function(module, attr, part)
        # On the classes: an environment may switch solvers (TrunkSpaceDebris: one per cube).
        clock.patch(type(base.sim), "step", "solver_other")
        clock.patch(type(base), "_observe", "observation")
        clock.patch(type(base), "_reward", "reward")
        clock.patch(type(base), "_info", "reward")
        done, wall, note = _rollout(env, env_steps, seed, clock)
    finally:
        clock.restore()
        env.close()
    shares = {part: seconds / wall for part, seconds in clock.seconds.items()}
    shares["glue"] = max(0.0, 1.0 - sum(shares.values()))
    return {
        "env": name,
        "dt": dt,
        "substeps": substeps,
        "env_steps": done,
        "ms_per_env_step": 1e3 * wall / done,
        "real_time_factor": done * substeps * dt / wall,
        "fractions": shares,
        "note": note,
    }


#: column names of the profile's table (its caption spells them out)
_SHORT = {
    "collision": "coll",
    "forces": "forc",
    "assembly": "asm",
    "factorisation": "fact",
    "solves": "solv",
    "tangent_lag": "lag",
    "compliance": "W",
    "constraint_rows": "rows",
    "constraint_solve": "QP",
    "solver_other": "othr",
    "observation": "obs",
    "reward": "rew",
    "glue": "glue",
}


def report_env_profile(
    names: list[str] | None, *, quick: bool, out: Path, console: Console, env_steps: int = 10
) -> list[dict]:
    """Profile each environment (or `names`) at dt 0.01, print the shares and write the JSON
    (`pliant bench --env-profile`)."""
    _check_names(names)
    rows = []
    for name in names or sorted(ENVS):
        kwargs = dict(ENVS[name].quick) if quick else {}
        kwargs.pop("substeps", None)
        try:
            rows.append(profile_env(name, env_steps=env_steps, **kwargs))
        except Exception as exc:  # a failure is a result of the benchmark: report it
            rows.append({"env": name, "dt": 0.01, "note": repr(exc)})
    parts = (*ENV_PARTS, "solver_other", "observation", "reward", "glue")
    table = Table(
        title="where an environment step's time goes (% of the step, dt 0.01)",
        box=box.SIMPLE,
        caption=", ".join(f"{_SHORT[p]}: {p.replace('_', ' ')}" for p in parts),
    )
    for col in ("env", "RTF", *(_SHORT[p] for p in parts)):
        table.add_column(col)
    for r in rows:
        if "fractions" not in r:
            table.add_row(r["env"], "", *[""] * len(parts))
            continue
        shares = [f"{100 * r['fractions'][p]:.0f}" for p in parts]
        table.add_row(r["env"], f"{r['real_time_factor']:.2f}", *shares)
    return _save(rows, table, quick=quick, out=out, console=console)


def vector_throughput(
    name: str,
    copies: int = 2,
    *,
    steps: int = 4,
    repeats: int = 9,
    modes: tuple[str, ...] = ("sequential", "threads", "subproc"),
    **kwargs,
) -> dict:
    """Environment steps per second (all copies) of `copies` copies of `name` stepped in
    turn in one process ("sequential"), at the same time on threads of one process
    ("threads": what releases the GIL, the compiled kernels and CHOLMOD, overlaps, as in
    :class:`pliant.solvers.BatchedImplicitEuler`), and in spawned worker processes
    (:func:`pliant.envs.make_subproc_vec_env`, "subproc"); each repeat times `steps` vector
    steps of every mode in turn (interleaved), medians over `repeats` and every repeat."""
    envs = [make(f"pliant/{name}-v0", **kwargs) for _ in range(copies)]
    for i, env in enumerate(envs):
        env.reset(seed=i)
        env.action_space.seed(i)
    pool = ThreadPoolExecutor(copies)
    workers = (
        make_subproc_vec_env(f"pliant/{name}-v0", copies, seed=0, **kwargs)
        if "subproc" in modes
        else None
    )
    space = envs[0].action_space

    def one(env) -> None:
        _, _, terminated, truncated, _ = env.step(env.action_space.sample())
        if terminated or truncated:
            env.reset()

    steppers = {
        "sequential": lambda: [one(env) for env in envs],
        "threads": lambda: list(pool.map(one, envs)),
        "subproc": lambda: workers.step(np.array([space.sample() for _ in range(copies)])),
    }
    runs: dict[str, list[float]] = {mode: [] for mode in modes}
    try:
        if workers is not None:
            workers.reset()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            for mode in modes:  # compilation, first factorisations
                steppers[mode]()
            for _ in range(repeats):
                for mode in modes:
                    start = time.perf_counter()
                    for _ in range(steps):
                        steppers[mode]()
                    runs[mode].append(copies * steps / (time.perf_counter() - start))
    finally:
        pool.shutdown()
        if workers is not None:
            workers.close()
        for env in envs:
            env.close()
    return {
        "env": name,
        "copies": copies,
        "steps": steps,
        "repeats": repeats,
        "env_steps_per_s": {mode: statistics.median(v) for mode, v in runs.items()},
        "runs": runs,
    }
