"""Snapshots of a full simulation for the reduction: positions recorded along load cases.

A load case drives the model with commands as a function of time (a phase of one actuator, a
gait, a sequence of environment actions) over a duration; the full FEM
(:class:`pliant.solvers.ImplicitEuler`) steps it and every `every` steps its positions are
appended to an HDF5 file, one group per case:

    /cases/<name>/positions   (s, n, 3)   recorded positions
    /cases/<name>/times       (s,)
    /cases/<name>/checkpoint  the full State after the last recorded step
    attributes: done, steps; at the root: fingerprint, dt, every

(a file holds finished cases only).

The collection is resumable, and a resumed collection holds the same numbers, bit for bit, as
one never interrupted, however it was stopped (SIGKILL included). The lagged factorisation
of the tangent restarts after each record (``LinearisedSystem.invalidate``), so that a record
depends on the state recorded before it only. Cases run one after the other in this process
(`workers=1`), where each record of the case under way is saved at once as a state file,
atomically, in the folder ``<path>.parts/<case>/``: an interrupted case continues from its last
intact record; or each on a worker, local processes or Ray tasks
(:func:`pliant.processes.run_jobs`, as the condensed-data collection runs its chunks), from
rest to its end: an interrupted parallel collection keeps its finished cases and runs the
others again from rest. The HDF5 file itself is never modified in place: each finished case
is added to a copy that replaces it (``pliant.files.atomic_path``), so that a kill leaves the
previous file whole. The datasets carry HDF5's Fletcher-32 checksums: a finished case that
fails its checksum on resuming is collected again (with a warning).
"""

from __future__ import annotations

import os
import pickle
import shutil
import warnings
from collections.abc import Callable, Iterator, Sequence
from contextlib import closing
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pliant.errors import ContactConvergenceWarning, ReductionError, StateError
from pliant.files import atomic_path, read_checked
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
        ReductionError: the file holds snapshots of another mesh, time step or period, is not
            a readable snapshot file (named), or a case's commands do not pickle for local
            workers.
        WorkerError: a local worker died; the cases finished are kept, the same call resumes.
    """
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ReductionError(f"workers must be an integer >= 1, got {workers!r}")
    path = Path(path)
    parts = path.with_name(path.name + ".parts")
    settings = {"fingerprint": mesh_fingerprint(model.body), "dt": float(dt), "every": every}
    if path.exists():
        done, corrupt = _finished_cases(path, settings, [case.name for case in cases])
    else:  # progress kept beside a file that is gone belongs to no file
        shutil.rmtree(parts, ignore_errors=True)
        done, corrupt = set(), []
    if corrupt or not path.exists():
        _write_cases(path, settings, {}, drop=corrupt)
    todo = [case for case in cases if case.name not in done]
    if workers == 1 and ray_address is None:
        for case in todo:
            _collect_here(model, case, path, settings, dt, every, progress)
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
            # an unfinished case of an earlier serial call ran again from rest
            _write_cases(path, settings, {name: (times, positions, state, steps[name])})
            shutil.rmtree(parts / name, ignore_errors=True)
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
    """The states of `case` to record (every `every` steps and the last), from `state`. The
    lagged tangent restarts after each record: the steps after a record depend on it only, so
    that a case resumed from a record (in another process) goes on bit for bit."""
    steps = case.steps(dt)
    solver = ImplicitEuler(model, dt)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ContactConvergenceWarning)
        while state.step < steps:
            state = solver.step(state, case.commands(state.time))
            if state.step % every == 0 or state.step == steps:
                yield state
                solver.system.invalidate()


def _collect_here(model, case, path: Path, settings: dict, dt, every, progress) -> None:
    """Run `case` in this process, each record saved at once (atomically) as a state file in
    ``<path>.parts/<case>/``; an unfinished case of an earlier call continues from its last
    intact record (the damaged ones, a write cut short, dropped with a warning). The finished
    case goes into the HDF5 file, and its records are deleted."""
    folder = path.with_name(path.name + ".parts") / case.name
    states = _saved_records(model, folder)
    start = states[-1] if states else model.rest_state()
    steps = case.steps(dt)
    for state in _recorded(model, case, dt, every, start):
        folder.mkdir(parents=True, exist_ok=True)
        state.save(folder / f"{state.step:09d}.npz")
        states.append(state)
        if progress is not None:
            progress(case.name, state.step, steps)
    times = np.array([s.time for s in states])
    positions = np.array([s.positions for s in states])
    _write_cases(path, settings, {case.name: (times, positions, states[-1], steps)})
    shutil.rmtree(folder, ignore_errors=True)


def _saved_records(model: Model, folder: Path) -> list[State]:
    """The records of an unfinished case, in order, up to the first damaged one (which, and
    any after it, is deleted with a CorruptCaseWarning)."""
    if not folder.is_dir():
        return []
    files = sorted(p for p in folder.glob("*.npz") if p.stem.isdigit())
    states = []
    for k, file in enumerate(files):
        try:
            states.append(State.load(file, model))
        except StateError as exc:
            warnings.warn(
                f"{file}: a damaged record ({exc}): the case goes on from the record before it",
                CorruptCaseWarning,
                stacklevel=4,
            )
            for later in files[k:]:
                later.unlink(missing_ok=True)
            break
    return states


def _finished_cases(path: Path, settings: dict, names: Sequence[str]) -> tuple[set, list]:
    """(the cases of `names` finished and sound in `path`, those finished that fail their
    checksum: to collect again, with a warning); ReductionError for a file of other settings
    or one that is not a snapshot file."""
    h5py = _h5py()

    def read(p: Path) -> tuple[set, list]:
        with h5py.File(p, "r") as f:
            for key, value in settings.items():
                if key in f.attrs and f.attrs[key] != value:
                    raise ReductionError(
                        f"{p} holds snapshots with {key} = {f.attrs[key]!r}, not {value!r}: use"
                        " another file for these settings"
                    )
            group = f.get("cases")
            found = [n for n in names if group is not None and n in group]
            done, corrupt = set(), []
            for name in found:
                if not group[name].attrs.get("done", False):
                    corrupt.append(name)  # a file of an earlier Pliant, cut mid-case
                    continue
                try:
                    group[name]["positions"][()], group[name]["times"][()]
                except OSError as exc:  # Fletcher-32 mismatch, unreadable chunk
                    warnings.warn(
                        f"{p}: load case {name!r} is unreadable or fails its checksum ({exc}):"
                        " collected again",
                        CorruptCaseWarning,
                        stacklevel=5,
                    )
                    corrupt.append(name)
                    continue
                done.add(name)
            return done, corrupt

    return read_checked(path, read, "a snapshot file (HDF5)", ReductionError)


def _write_cases(path: Path, settings: dict, cases: dict, drop: Sequence[str] = ()) -> None:
    """Add finished `cases` {name: (times, positions, last state, steps)} to the file, and
    delete those of `drop`: on a copy that then replaces it, so that the file is always whole."""
    h5py = _h5py()
    with atomic_path(path) as tmp:
        if path.exists():
            shutil.copyfile(path, tmp)
        with h5py.File(tmp, "a") as f:
            for key, value in settings.items():
                f.attrs[key] = value
            group = f.require_group("cases")
            for name in [*drop, *cases]:
                if name in group:
                    del group[name]
            for name, (times, positions, state, steps) in cases.items():
                case = _new_case(group, name, positions.shape[1])
                _append(case, times, positions)
                _finish(case, state, steps)


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


def _finish(group, state: State, steps: int) -> None:
    """Mark a case done (after its last record and its checkpoint `state`)."""
    _write_state(group, state)
    group.attrs["steps"] = steps
    group.attrs["done"] = True


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
    """{case: (times (s,), positions (s, n, 3))} of a snapshot file (its cases, or those
    named); ReductionError for another mesh, NaN positions, or a file that is not a readable
    snapshot file (named)."""
    path = Path(path)
    if not path.exists():
        raise ReductionError(f"no snapshot file at {path}")
    h5py = _h5py()

    def read(p: Path) -> dict:
        out = {}
        with h5py.File(p, "r") as f:
            if model is not None and f.attrs.get("fingerprint") != mesh_fingerprint(model.body):
                raise ReductionError(
                    f"{p} holds snapshots of another mesh than {model.name}'s"
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

    return read_checked(path, read, "a snapshot file (HDF5)", ReductionError)
