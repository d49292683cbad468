"""Snapshots of a full simulation for the reduction: positions recorded along load cases.

A load case drives the model with commands as a function of time (a phase of one actuator, a
gait, a sequence of environment actions) over a duration; the full FEM
(:class:`pliant.solvers.ImplicitEuler`) steps it and every `every` steps its positions are
appended to an HDF5 file, one group per case:

    /cases/<name>/positions   (s, n, 3)   recorded positions
    /cases/<name>/times       (s,)
    /cases/<name>/checkpoint  the full State after the last recorded step
    attributes: done, steps; at the root: fingerprint, dt, every

The collection is resumable: a finished case is skipped. Cases run one after the other in
this process (`workers=1`), where an interrupted case continues from its checkpoint (close to
an uninterrupted run: only the lagged factorisation restarts there, 1e-6 mm apart on the
tests' beam); or each on a worker, local processes or Ray tasks
(:func:`pliant.processes.run_jobs`, as the condensed-data collection runs its chunks), from
rest to its end, and written as a whole when it is done: an interrupted parallel collection
keeps its finished cases and runs the others again from rest, so that the file holds the
same numbers, bit for bit, as a serial collection without interruption. The datasets carry
HDF5's Fletcher-32 checksums: a finished case that fails its checksum on resuming is
collected again (with a warning).
"""

from __future__ import annotations

import os
import pickle
import warnings
from collections.abc import Callable, Iterator, Sequence
from contextlib import closing
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pliant.constraints.friction import ContactForces
from pliant.errors import ContactConvergenceWarning, ReductionError
from pliant.model import Model, State
from pliant.processes import run_jobs
from pliant.reduction.basis import check_snapshots, mesh_fingerprint
from pliant.solvers import ImplicitEuler


class CorruptCaseWarning(UserWarning):
    """A finished load case of a snapshot file failed its checksum: it is collected again."""


@dataclass(frozen=True)
class LoadCase:
    """Commands as a function of time (s) over `duration` seconds, named (the HDF5 group)."""

    name: str
    commands: Callable[[float], np.ndarray]
    duration: float

    def steps(self, dt: float) -> int:
        """Steps of `dt` that the case lasts (at least one)."""
        return max(1, round(self.duration / dt))


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
    workers: int = 1,
    ray_address: str | None = None,
    progress: Callable[[str, int, int], None] | None = None,
) -> Path:
    """Run the load cases with the full FEM and record positions in the HDF5 file `path`
    (module docstring); returns the path.

    Args:
        workers: 1 runs the cases in this process; more runs them on as many local processes
            (spawned; their commands must pickle: module-level functions, functools.partial,
            :class:`pliant.reduction.pipeline.RampedCommands`).
        ray_address: run the cases as Ray tasks on this cluster instead ("auto", "local",
            "ray://host:port"), `workers` of them at a time when more than 1.
        progress: called with (case, step, steps) after each recorded step (in this process),
            or after each case is written (on workers).

    Raises:
        ReductionError: the file holds snapshots of another mesh, time step or period, or a
            case's commands do not pickle for local workers.
        WorkerError: a local worker died; the cases finished are kept, the same call resumes.
    """
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ReductionError(f"workers must be an integer >= 1, got {workers!r}")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    n = model.body.n_nodes
    with _h5py().File(path, "a") as f:
        settings = {"fingerprint": mesh_fingerprint(model.body), "dt": float(dt), "every": every}
        for key, value in settings.items():
            if key in f.attrs and f.attrs[key] != value:
                raise ReductionError(
                    f"{path} holds snapshots with {key} = {f.attrs[key]!r}, not {value!r}: use"
                    " another file for these settings"
                )
            f.attrs[key] = value
        cases_group = f.require_group("cases")
        todo = [case for case in cases if not _finished(cases_group, case.name, path)]
        if workers == 1 and ray_address is None:
            for case in todo:
                _collect_here(model, case, cases_group, dt, every, progress)
            return path
        if ray_address is None:
            _check_pickles(todo)
        threads = None if ray_address else max(1, (os.cpu_count() or 1) // workers)
        # the longest first: the last case to start is then a short one
        todo.sort(key=lambda case: -case.steps(dt))
        jobs = [(case.name, (model, case, dt, every, threads)) for case in todo]
        steps = {case.name: case.steps(dt) for case in todo}
        results = run_jobs(
            record_case,
            jobs,
            workers=workers if ray_address is None or workers > 1 else None,
            ray_address=ray_address,
            what="load case",
        )
        with closing(results):  # on an error here, the workers stop at once
            for name, (times, positions, state) in results:
                if name in cases_group:  # an unfinished case of an earlier call: from rest
                    del cases_group[name]
                group = _new_case(cases_group, name, n)
                _append(group, times, positions)
                _finish(group, state, steps[name])
                f.flush()
                if progress is not None:
                    progress(name, steps[name], steps[name])
    return path


def record_case(
    model: Model, case: LoadCase, dt: float, every: int, threads: int | None = None
) -> tuple[np.ndarray, np.ndarray, State]:
    """(times, positions, last state) of `case` run from rest: what a worker computes.
    `threads`: numba's threads in this process (a worker shares the cores with others)."""
    if threads is not None:
        import numba

        numba.set_num_threads(min(threads, numba.config.NUMBA_NUM_THREADS))
    states = list(_recorded(model, case, dt, every, model.rest_state()))
    return (
        np.array([s.time for s in states]),
        np.array([s.positions for s in states]),
        states[-1],
    )


def _recorded(model: Model, case: LoadCase, dt: float, every: int, state: State) -> Iterator[State]:
    """The states of `case` to record (every `every` steps and the last), from `state`."""
    steps = case.steps(dt)
    solver = ImplicitEuler(model, dt)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ContactConvergenceWarning)
        while state.step < steps:
            state = solver.step(state, case.commands(state.time))
            if state.step % every == 0 or state.step == steps:
                yield state


def _collect_here(model, case, cases_group, dt, every, progress) -> None:
    """Run `case` in this process, appending each record and the checkpoint as it comes. An
    unfinished case of an earlier call continues from its checkpoint (the records after it,
    if a write was cut short, dropped), or from rest if it has none."""
    group = cases_group.get(case.name)
    if group is not None and "checkpoint" in group:
        start = _read_state(group)
        kept = int(np.searchsorted(group["times"][()], start.time, side="right"))
        group["positions"].resize(kept, axis=0)
        group["times"].resize(kept, axis=0)
    else:
        if group is not None:
            del cases_group[case.name]
        group = _new_case(cases_group, case.name, model.body.n_nodes)
        start = model.rest_state()
    steps = case.steps(dt)
    for state in _recorded(model, case, dt, every, start):
        _append(group, np.array([state.time]), state.positions[None])
        _write_state(group, state)
        group.file.flush()
        if progress is not None:
            progress(case.name, state.step, steps)
    _finish(group, None, steps)


def _new_case(cases_group, name: str, n: int):
    group = cases_group.create_group(name)
    group.create_dataset(
        "positions", (0, n, 3), "f8", maxshape=(None, n, 3), chunks=(1, n, 3), fletcher32=True
    )
    group.create_dataset("times", (0,), "f8", maxshape=(None,), chunks=(64,), fletcher32=True)
    return group


def _append(group, times: np.ndarray, positions: np.ndarray) -> None:
    k = group["positions"].shape[0]
    group["positions"].resize(k + len(times), axis=0)
    group["times"].resize(k + len(times), axis=0)
    group["positions"][k:] = positions
    group["times"][k:] = times


def _finish(group, state: State | None, steps: int) -> None:
    """Mark a case done (after its last record, and its checkpoint `state` when given)."""
    if state is not None:
        _write_state(group, state)
    group.attrs["steps"] = steps
    group.attrs["done"] = True


def _finished(cases_group, name: str, path: Path) -> bool:
    """Whether the case `name` is done and sound; a done case that fails its checksum is
    deleted (to be collected again), with a warning."""
    group = cases_group.get(name)
    if group is None or not group.attrs.get("done", False):
        return False
    try:
        group["positions"][()], group["times"][()]
    except OSError as exc:  # Fletcher-32 mismatch, unreadable chunk
        warnings.warn(
            f"{path}: load case {name!r} is unreadable or fails its checksum ({exc}): collected"
            " again",
            CorruptCaseWarning,
            stacklevel=4,
        )
        del cases_group[name]
        return False
    return True


def _check_pickles(cases: Sequence[LoadCase]) -> None:
    for case in cases:
        try:
            pickle.dumps(case.commands)
        except (pickle.PicklingError, AttributeError, TypeError) as exc:
            raise ReductionError(
                f"the commands of load case {case.name!r} do not pickle ({exc}), so local"
                " workers cannot run it: give a module-level function, a functools.partial or"
                " a pliant.reduction.pipeline.RampedCommands (or workers=1)"
            ) from exc


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
