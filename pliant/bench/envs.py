"""Environment speed: environment steps and simulation steps per second, and the real-time
factor RTF = simulated time / wall time (thesis Eq. 3.1), at several time steps.

An environment step lasts the same simulated time at every dt (the sub-steps scale as 1/dt), so
that the figures compare the same task. Actions are random (seeded) and the episode restarts
when it ends; the first step (compilation, first factorisation) is not timed.
"""

from __future__ import annotations

import json
import time
import warnings
from dataclasses import asdict, dataclass
from pathlib import Path

from rich.console import Console
from rich.table import Table

from pliant.envs import ENVS, make
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


def measure_env(
    name: str, dt: float = 0.01, *, env_steps: int = 10, seed: int = 0, **kwargs
) -> EnvSpeed:
    """Time `env_steps` environment steps of `name` at time step `dt` (default settings, or
    `kwargs`)."""
    spec_env = make(f"pliant/{name}-v0", **kwargs)
    base = spec_env.unwrapped
    step_time = base.step_time
    spec_env.close()
    substeps = max(1, round(step_time / dt))
    env = make(f"pliant/{name}-v0", dt=dt, substeps=substeps, **kwargs)
    env.action_space.seed(seed)
    diverged = ""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        env.reset(seed=seed)
        env.step(env.action_space.sample())  # compilation and first factorisation
        wall, done = 0.0, 0
        while done < env_steps:
            action = env.action_space.sample()
            clock = time.perf_counter()
            _, _, term, trunc, info = env.step(action)
            wall += time.perf_counter() - clock
            done += 1
            if "diverged" in info:
                diverged = info["diverged"]
                break
            if term or trunc:
                env.reset()
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


def report_envs(names: list[str] | None, *, quick: bool, out: Path, console: Console) -> list:
    """Measure, print a table and write the JSON (`pliant bench --envs`)."""
    unknown = sorted(set(names or []) - set(ENVS))
    if unknown:
        raise UnknownRobotError(f"unknown environments {unknown}; available: {sorted(ENVS)}")
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
    console.print(table)
    out.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(out) as tmp:
        tmp.write_text(json.dumps({"environments": rows, "quick": quick}, indent=1))
    console.print(f"saved {out}")
    return rows
