"""Data acquisition (thesis §5.1.2): the robot solved quasi-statically at every planned sample.

The samples are cut into chunks of `plan.chunk_size`. A worker solves a chunk in a row, each
sample load-stepped from the previous one's equilibrium (Newton converges where a jump from rest
would not; the first of each design from its rest equilibrium) or, with ``plan.start ==
"rest"``, from its design's rest equilibrium (a robot with several equilibria for one command);
so a chunk's result does not depend on which worker solves it, nor when. Every finished chunk
is written at once, atomically, next to the output file (`OUT.parts/`): an interrupted
collection loses nothing already computed, and the next call with the same plan solves only
the missing chunks and gives the same dataset.

Chunks run on local processes (default), in this process (`workers=1`), or on a Ray cluster
(`ray_address`, e.g. "auto" for the cluster this machine belongs to). Local workers end with
their parent (:mod:`pliant.processes`); a worker that dies ends the collection with a
WorkerError, the chunks saved kept for the next call.

Each chunk file holds a checksum of its values: a chunk found corrupt on resuming is solved
again, and :func:`verify` names the bad ones.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import json
import os
import shutil
import warnings
import zipfile
from collections.abc import Callable
from contextlib import closing
from dataclasses import fields
from pathlib import Path

import numpy as np

from pliant import robots
from pliant.condensed.contact import ContactRobot, contact_points, failed_row, sample_row
from pliant.condensed.dataset import (
    SPLITS,
    CollectionPlan,
    Dataset,
    Split,
    atomic_write,
    checksum,
)
from pliant.condensed.dataset import verify as verify_dataset
from pliant.condensed.layout import Layout
from pliant.condensed.manipulation import grasp_chunk
from pliant.errors import DatasetError, DivergenceError, ModelError
from pliant.model import Model
from pliant.processes import run_jobs


class CorruptChunkWarning(UserWarning):
    """A saved chunk of a partial collection failed its checksum: it is solved again."""


ChunkKey = tuple[str, int, int]  # split, first sample, end


def collect(
    plan: CollectionPlan,
    out: str | os.PathLike,
    *,
    workers: int | None = None,
    ray_address: str | None = None,
    on_chunk: Callable[[int, int], None] | None = None,
    overwrite: bool = False,
) -> Dataset:
    """Solve every sample of `plan` and write the dataset to `out` (HDF5); resume a partial
    collection of the same plan if one is there (its chunks checked, the corrupt ones solved
    again).

    Args:
        workers: local worker processes (default: one per CPU); 1 solves in this process.
        ray_address: run the chunks on this Ray cluster instead ("auto", "ray://host:port").
        on_chunk: called with (samples done, samples in all) after each chunk is saved.
        overwrite: replace `out` if it exists, and a partial collection of another plan.

    Raises:
        DatasetError: `out` exists (without `overwrite`), a partial collection of another plan
            is there, or a chunk or the dataset cannot be written (disk full: the chunks saved
            are kept, and the same call resumes).
        WorkerError: a worker process died; the same call resumes.
    """
    out = Path(out)
    if workers is not None and (
        isinstance(workers, bool) or not isinstance(workers, int) or workers < 1
    ):
        raise DatasetError(f"workers must be None or an integer >= 1, got {workers!r}")
    if out.exists() and not overwrite:
        raise DatasetError(
            f"{out} already exists; pass --overwrite (overwrite=True) to replace it, check it"
            " with 'pliant condensed verify', or write the dataset elsewhere"
        )
    if out.is_dir():
        raise DatasetError(f"{out} is a folder; the dataset is a file")
    layout = _layout(plan)
    parts = _parts_folder(out, plan, restart=overwrite)
    points = plan.points()
    chunks = _chunks(plan, points, SPLITS)
    total = sum(len(p) for p in points.values())
    solved = {key: split for key in chunks if (split := _saved_chunk(parts, key)) is not None}
    done = sum(stop - start for _, start, stop in solved)
    jobs = [(key, (plan, points[key[0]][key[1] : key[2]])) for key in chunks if key not in solved]
    results = run_jobs(
        solve_chunk, jobs, workers=None if ray_address else workers, ray_address=ray_address
    )
    with closing(results):
        for key, split in results:
            _save_chunk(_chunk_path(parts, key), split, len(solved))
            solved[key] = split
            done += key[2] - key[1]
            if on_chunk is not None:
                on_chunk(done, total)
    empty = Split.empty(Split.widths(plan, layout))
    splits = {
        name: Split.concatenate([empty, *(solved[k] for k in chunks if k[0] == name)])
        for name in SPLITS
    }
    dataset = Dataset(plan, layout, splits["train"], splits["test"])
    try:
        dataset.save(out)
    except OSError as exc:
        raise DatasetError(
            f"cannot write {out}: {exc}; every chunk is saved in {parts}: free space (or fix"
            " the folder) and rerun the same command to write it"
        ) from exc
    shutil.rmtree(parts)
    return dataset


def solve_split(plan: CollectionPlan, split: str, *, workers: int | None = None) -> Split:
    """The samples of one split of `plan` solved again, chunk by chunk as `collect` solves
    them: the same samples as that split of the plan's dataset, without the other split (the
    test set of a kept model re-made from the plan stored in it). Nothing is written."""
    if split not in SPLITS:
        raise DatasetError(f"split must be one of {SPLITS}, got {split!r}")
    points = plan.points()
    chunks = _chunks(plan, points, (split,))
    jobs = [(key, (plan, points[split][key[1] : key[2]])) for key in chunks]
    solved = dict(run_jobs(solve_chunk, jobs, workers=workers))
    empty = Split.empty(Split.widths(plan, _layout(plan)))
    return Split.concatenate([empty, *(solved[key] for key in chunks)])


def held_out_split(plan: CollectionPlan, seed: int, *, workers: int | None = None) -> Split:
    """A held-out test set for a model trained on `plan`: the test split of the same plan
    drawn from another `seed` (the same box, count and robot), solved as `collect` solves it,
    converged samples only. Deterministic: the same samples every time, so it can be drawn
    after every choice was made on the plan's own test split (then a validation set) and
    re-made from the plan a kept model records."""
    if seed == plan.seed:
        raise DatasetError(f"a held-out seed must differ from the plan's ({plan.seed})")
    return solve_split(
        dataclasses.replace(plan, seed=seed), "test", workers=workers
    ).converged_only()


def _chunks(plan: CollectionPlan, points: dict[str, np.ndarray], splits) -> list[ChunkKey]:
    return [
        (split, start, min(start + plan.chunk_size, len(points[split])))
        for split in splits
        for start in range(0, len(points[split]), plan.chunk_size)
    ]


def _layout(plan: CollectionPlan) -> Layout:
    model = _build(plan.robot, json.dumps(plan.robot_kwargs, sort_keys=True))
    return Layout.of(model, [contact_points(model, plan.contacts)] if plan.contacts else [])


def verify(out: str | os.PathLike) -> list[str]:
    """Problems found in the dataset file `out` and in the chunks of its partial collection
    (`out`.parts/), one line each naming the part; empty when all is sound. A chunk listed is
    solved again by the next `collect` of the same plan."""
    out = Path(out)
    parts = out.with_name(out.name + ".parts")
    if not out.exists() and not parts.is_dir():
        return [f"no dataset at {out} and no partial collection at {parts}"]
    problems = verify_dataset(out) if out.exists() else []
    if parts.is_dir():
        plan_file = parts / "plan.json"
        try:
            CollectionPlan.from_dict(json.loads(plan_file.read_text()))
        except (OSError, ValueError, TypeError, KeyError, DatasetError) as exc:
            problems.append(f"{plan_file} is unreadable or not a plan: {exc}")
        for path in sorted(parts.glob("*.npz")):
            try:
                _load_chunk(path)
            except DatasetError as exc:
                problems.append(str(exc))
    return problems


def load_or_collect(
    plan: CollectionPlan,
    out: str | os.PathLike,
    *,
    workers: int | None = None,
    ray_address: str | None = None,
    on_chunk: Callable[[int, int], None] | None = None,
) -> Dataset:
    """The dataset at `out` if it was collected with `plan`, else `collect` it there (resuming
    a partial collection); DatasetError if `out` holds another plan's dataset."""
    out = Path(out)
    if not out.exists():
        return collect(plan, out, workers=workers, ray_address=ray_address, on_chunk=on_chunk)
    dataset = Dataset.load(out)
    if dataset.plan != plan:
        differs = sorted(k for k, v in plan.to_dict().items() if dataset.plan.to_dict().get(k) != v)
        raise DatasetError(
            f"{out} was collected with another plan (differs in {differs}); delete it or"
            " write the dataset elsewhere"
        )
    return dataset


def solve_chunk(plan: CollectionPlan, points: np.ndarray) -> Split:
    """Equilibria at consecutive samples (rows: actuator commands, the object's displacement,
    then design parameters; `grasp_chunk` for gripper sampling). With contact points, each
    sample first releases them at its actuator commands (no contact force), then holds them
    displaced rigidly from there by the object's displacement: the contact forces stay of the
    order of that displacement (held at absolute positions, contact points a millimetre away
    from where the cables take them load the finger with tens of newtons: states no task
    visits, the thesis' argument for sampling relevant ones).

    Every design's effectors get the goals of the plan's base design (`robot_kwargs`), so that
    delta_e measures effector positions from the same point whatever the design. A design
    the builder rejects (:class:`ModelError`: a geometry the mesher cannot mesh) gives failed
    samples, as a static solve that diverges does, instead of ending the collection.
    """
    base_json = json.dumps(plan.robot_kwargs, sort_keys=True)
    if plan.sampling == "gripper":
        return grasp_chunk(plan, points, _build(plan.robot, base_json))
    n_act, n_cmd = len(plan.actuator_bounds), plan.n_commands
    goals = _training_goals(plan.robot, base_json) if plan.design_names else None
    rows: list[dict[str, np.ndarray]] = []
    design = None
    unbuilt: Layout | None = None  # the rows of a design the builder rejects (all failed)
    for point in np.atleast_2d(points):
        command, params = point[:n_cmd], point[n_cmd:]
        if design is None or not np.array_equal(params, design):
            design = params
            kwargs = {
                **plan.robot_kwargs,
                **dict(zip(plan.design_names, params.tolist(), strict=True)),
            }
            try:
                model = _build(plan.robot, json.dumps(kwargs, sort_keys=True))
            except ModelError:  # e.g. a geometry the mesher cannot recover: counted as failed
                unbuilt = ContactRobot.for_plan(_build(plan.robot, base_json), plan).layout
            else:
                unbuilt = None
                if goals is not None:
                    for effector, goal in zip(model.effectors, goals, strict=True):
                        effector.goals = goal
                robot = ContactRobot.for_plan(model, plan)
                rest = state = robot.rest()
                w0, free0 = robot.layout.pack(robot.problem(state))
        if unbuilt is not None:
            rows.append(failed_row(command, params, unbuilt))
            continue
        if plan.start == "rest":
            state = rest
        try:
            if plan.contacts:  # the object displaced from where the actuators put the points
                state = robot.release(state, command[:n_act])
                held = robot.object_rows(state, command[n_act:])
                state = robot.solve(state, command[:n_act], held)
            else:
                state = robot.solve(state, command)
        except DivergenceError:  # kept NaN; the next sample starts from the last equilibrium
            rows.append(failed_row(command, params, robot.layout))
            continue
        rows.append(sample_row(robot, state, command, params, (w0, free0)))
    return Split(**{f.name: np.array([r[f.name] for r in rows]) for f in fields(Split)})


@functools.lru_cache(maxsize=1)
def _training_goals(robot: str, kwargs_json: str) -> tuple[np.ndarray, ...]:
    """The effector goals of the base design (its effectors' rest positions by default)."""
    return tuple(e.goals.copy() for e in _build(robot, kwargs_json).effectors)


@functools.lru_cache(maxsize=1)
def _build(robot: str, kwargs_json: str) -> Model:
    """The robot, built once per process and design (meshing is the costly part)."""
    return robots.build(robot, **json.loads(kwargs_json))


def _parts_folder(out: Path, plan: CollectionPlan, *, restart: bool = False) -> Path:
    """OUT.parts/, holding plan.json and the finished chunks; refuses another plan's (starts
    over with `restart`)."""
    parts = out.with_name(out.name + ".parts")
    try:
        parts.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise DatasetError(f"cannot make the folder {parts} for the chunks: {exc}") from exc
    plan_file = parts / "plan.json"
    wanted = json.loads(json.dumps(plan.to_dict()))
    if plan_file.exists():
        try:
            found = json.loads(plan_file.read_text())
        except ValueError as exc:
            if not restart:
                raise DatasetError(
                    f"{plan_file} is corrupt: {exc}; pass --overwrite to start over"
                ) from exc
            found = None
        if found != wanted and restart:
            shutil.rmtree(parts)
            return _parts_folder(out, plan)
        if found != wanted:
            differs = sorted(
                k for k in wanted.keys() | found.keys() if wanted.get(k) != found.get(k)
            )
            raise DatasetError(
                f"the partial collection in {parts} was started with another plan (differs in"
                f" {differs}); collect with the same settings, or pass --overwrite to start over"
            )
    else:
        try:
            atomic_write(plan_file, lambda tmp: Path(tmp).write_text(json.dumps(wanted, indent=1)))
        except OSError as exc:
            raise DatasetError(f"cannot write {plan_file}: {exc}") from exc
    return parts


def _chunk_path(parts: Path, key: ChunkKey) -> Path:
    split, start, stop = key
    return parts / f"{split}-{start:07d}-{stop:07d}.npz"


def _chunk_checksum(arrays: dict[str, np.ndarray]) -> str:
    digest = hashlib.sha256()
    for name in sorted(arrays):
        digest.update(f"{name}:{checksum(arrays[name])};".encode())
    return digest.hexdigest()


def _save_chunk(path: Path, split: Split, saved: int) -> None:
    """Write a chunk atomically with its checksum; DatasetError (the `saved` chunks kept) if
    it cannot be written."""
    arrays = {f.name: getattr(split, f.name) for f in fields(Split)}
    try:
        atomic_write(path, lambda tmp: np.savez(tmp, sha256=_chunk_checksum(arrays), **arrays))
    except OSError as exc:
        raise DatasetError(
            f"cannot save the chunk {path.name}: {exc}; the {saved} chunks saved in"
            f" {path.parent} are kept: free space (or fix the folder) and rerun the same"
            " command to resume"
        ) from exc


def _load_chunk(path: Path) -> Split:
    """A saved chunk, its checksum verified (chunks saved before checksums: their zip CRCs)."""
    try:
        with np.load(path, allow_pickle=False) as data:
            arrays = {f.name: data[f.name] for f in fields(Split)}
            stored = str(data["sha256"]) if "sha256" in data.files else None
    except (OSError, KeyError, ValueError, EOFError, zipfile.BadZipFile) as exc:
        raise DatasetError(f"the saved chunk {path} is unreadable ({exc})") from exc
    if stored is not None and stored != _chunk_checksum(arrays):
        raise DatasetError(f"the saved chunk {path} fails its checksum (corrupt)")
    return Split(**arrays)


def _saved_chunk(parts: Path, key: ChunkKey) -> Split | None:
    """The chunk `key` saved by an earlier call, or None: not saved, or corrupt (deleted, with
    a warning, to be solved again)."""
    path = _chunk_path(parts, key)
    if not path.exists():
        return None
    try:
        split = _load_chunk(path)
        if len(split) != key[2] - key[1]:
            raise DatasetError(f"the saved chunk {path} has {len(split)} samples, not {key}")
    except DatasetError as exc:
        warnings.warn(f"{exc}: solved again", CorruptChunkWarning, stacklevel=3)
        path.unlink(missing_ok=True)
        return None
    return split
