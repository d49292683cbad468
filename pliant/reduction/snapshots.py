"""Snapshots of a full simulation for the reduction: positions recorded along load cases.

A load case drives the model with commands as a function of time (a phase of one actuator, a
gait, a sequence of environment actions) over a duration; the full FEM
(:class:`pliant.solvers.ImplicitEuler`) steps it and every `every` steps its positions are
appended to an HDF5 file, one group per case:

    /cases/<name>/positions   (s, n, 3)   recorded positions
    /cases/<name>/times       (s,)
    /cases/<name>/checkpoint  the full State after the last recorded step
    attributes: done, steps; at the root: fingerprint, dt, every

The collection is resumable: a finished case is skipped, an interrupted one continues from
its checkpoint (close to an uninterrupted run: only the lagged factorisation restarts there,
1e-6 mm apart on the tests' beam). Cases run one after the other in this process.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pliant.constraints.friction import ContactForces
from pliant.errors import ContactConvergenceWarning, ReductionError
from pliant.model import Model, State
from pliant.reduction.basis import check_snapshots, mesh_fingerprint
from pliant.solvers import ImplicitEuler


@dataclass(frozen=True)
class LoadCase:
    """Commands as a function of time (s) over `duration` seconds, named (the HDF5 group)."""

    name: str
    commands: Callable[[float], np.ndarray]
    duration: float


def _h5py():
    """h5py, imported when snapshots are written or read (an optional dependency, in the
    'learn' extra), with a clear error when it is missing."""
    try:
        import h5py
    except ImportError as exc:
        raise ReductionError(
            "snapshots are stored with h5py: pip install h5py (or pliant[learn])"
        ) from exc
    return h5py


def _write_state(group, state: State) -> None:
    if "checkpoint" in group:
        del group["checkpoint"]
    g = group.create_group("checkpoint")
    for name in ("positions", "velocities", "actuation", "displacement"):
        g[name] = getattr(state, name)
    g["contact_keys"] = state.contact_forces.keys
    g["contact_forces"] = state.contact_forces.forces
    g.attrs["time"], g.attrs["step"] = state.time, state.step


def _read_state(group) -> State:
    g = group["checkpoint"]
    return State(
        g["positions"][()],
        g["velocities"][()],
        float(g.attrs["time"]),
        int(g.attrs["step"]),
        g["actuation"][()],
        g["displacement"][()],
        ContactForces(g["contact_keys"][()], g["contact_forces"][()]),
    )


def collect(
    model: Model,
    cases: Sequence[LoadCase],
    path: str | Path,
    *,
    dt: float = 0.01,
    every: int = 5,
    progress: Callable[[str, int, int], None] | None = None,
) -> Path:
    """Run the load cases with the full FEM and record positions in the HDF5 file `path`
    (module docstring); returns the path. `progress(case, step, steps)` is called after each
    recorded step."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fingerprint = mesh_fingerprint(model.body)
    n = model.body.n_nodes
    with _h5py().File(path, "a") as f:
        settings = {"fingerprint": fingerprint, "dt": float(dt), "every": int(every)}
        for key, value in settings.items():
            if key in f.attrs and f.attrs[key] != value:
                raise ReductionError(
                    f"{path} holds snapshots with {key} = {f.attrs[key]!r}, not {value!r}: use"
                    " another file for these settings"
                )
            f.attrs[key] = value
        cases_group = f.require_group("cases")
        for case in cases:
            group = cases_group.require_group(case.name)
            if group.attrs.get("done", False):
                continue
            steps = max(1, round(case.duration / dt))
            if "positions" not in group:
                group.create_dataset(
                    "positions", (0, n, 3), "f8", maxshape=(None, n, 3), chunks=(1, n, 3)
                )
                group.create_dataset("times", (0,), "f8", maxshape=(None,))
            state = _read_state(group) if "checkpoint" in group else model.rest_state()
            solver = ImplicitEuler(model, dt)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", ContactConvergenceWarning)
                while state.step < steps:
                    state = solver.step(state, case.commands(state.time))
                    if state.step % every == 0 or state.step == steps:
                        k = group["positions"].shape[0]
                        group["positions"].resize(k + 1, axis=0)
                        group["times"].resize(k + 1, axis=0)
                        group["positions"][k] = state.positions
                        group["times"][k] = state.time
                        _write_state(group, state)
                        f.flush()
                        if progress is not None:
                            progress(case.name, state.step, steps)
            group.attrs["done"] = True
            group.attrs["steps"] = steps
    return path


def load(path: str | Path, model: Model | None = None, cases: Sequence[str] | None = None) -> dict:
    """{case: (times (s,), positions (s, n, 3))} of a snapshot file (the finished and
    unfinished cases, or those named); ReductionError for another mesh or NaN positions."""
    path = Path(path)
    if not path.exists():
        raise ReductionError(f"no snapshot file at {path}")
    out = {}
    with _h5py().File(path, "r") as f:
        if model is not None and f.attrs.get("fingerprint") != mesh_fingerprint(model.body):
            raise ReductionError(
                f"{path} holds snapshots of another mesh than {model.name}'s"
                f" ({f.attrs.get('fingerprint')} != {mesh_fingerprint(model.body)})"
            )
        for name, group in f["cases"].items():
            if cases is not None and name not in cases:
                continue
            positions = group["positions"][()]
            if len(positions):
                check_snapshots(positions, positions.shape[1])
            out[name] = (group["times"][()], positions)
    return out
