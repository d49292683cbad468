"""Snapshots -> POD basis -> ECSW integration domain -> a saved reduced model, and the load
cases that train the Multigait's."""

from __future__ import annotations

import functools
import hashlib
import json
import os
import tempfile
import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pliant.errors import ContactConvergenceWarning, PliantError
from pliant.mesh.multigait import CHAMBERS
from pliant.model import Model
from pliant.reduction import snapshots as snap
from pliant.reduction.basis import check_tolerance, mesh_fingerprint, pod
from pliant.reduction.ecsw import hyper_reduce
from pliant.reduction.reduced import ReducedModel
from pliant.reduction.snapshots import LoadCase
from pliant.robots.multigait import demo_actuation
from pliant.solvers import ImplicitEuler


def build(
    model: Model,
    positions: np.ndarray,
    *,
    pod_tolerance: float = 1e-3,
    tau: float = 0.03,
    tau_membrane: float = 0.05,
    translation: bool | None = None,
    max_modes: int | None = None,
    training: int = 40,
    metadata: dict | None = None,
) -> ReducedModel:
    """The reduced model of `model` from position snapshots (s, n, 3): the POD basis, then
    ECSW trained on `training` of the snapshots (evenly spaced) projected on the basis.
    The metadata records the sizes, the tolerances, the ECSW errors on the training set and
    the projection error of the snapshots (the best the basis can do)."""
    began = time.perf_counter()
    for name, value in (("the POD tolerance", pod_tolerance), ("tau", tau)):
        check_tolerance(name, value)
    body = model.body
    basis = pod(
        body, positions, tolerance=pod_tolerance, translation=translation, max_modes=max_modes
    )
    pod_seconds = time.perf_counter() - began
    pick = np.unique(np.linspace(0, len(positions) - 1, min(training, len(positions))).round())
    projected = np.array([basis.positions(basis.coordinates(q)) for q in positions])
    error = np.linalg.norm(projected - positions, axis=2)
    domain = hyper_reduce(
        body, basis, projected[pick.astype(int)], tau=tau, tau_membrane=tau_membrane
    )
    s = basis.singular_values
    kept = basis.n_modes - basis.n_translation
    meta = {
        "robot": model.name,
        "n_nodes": body.n_nodes,
        "n_modes": basis.n_modes,
        "n_translation": basis.n_translation,
        "pod_tolerance": pod_tolerance,
        "pod_tail_energy": float(np.sqrt(np.sum(s[kept:] ** 2) / np.sum(s**2))),
        "tau": tau,
        "tau_membrane": tau_membrane,
        "tets_selected": int(domain.tets.elements.size),
        "tets_total": body.n_elements,
        "triangles_selected": [int(m.elements.size) for m in domain.membranes],
        "triangles_total": [len(a.membrane.triangles) for a in body.membranes],
        "ecsw_error_tets": domain.tets.error,
        "ecsw_error_membranes": [m.error for m in domain.membranes],
        "snapshots": len(positions),
        "training_snapshots": int(pick.size),
        "projection_error_max_mm": float(error.max()),
        "projection_error_rms_mm": float(np.sqrt(np.mean(error**2))),
        "pod_seconds": pod_seconds,
        "build_seconds": time.perf_counter() - began,
        **(metadata or {}),
    }
    return ReducedModel(basis, domain, meta)


def reduce(
    model: Model,
    cases: Sequence[LoadCase],
    folder: str | Path,
    *,
    dt: float = 0.01,
    every: int = 5,
    workers: int = 1,
    ray_address: str | None = None,
    progress: Callable[[str, int, int], None] | None = None,
    **options,
) -> ReducedModel:
    """Collect the snapshots of `cases` (resumable, `folder`/snapshots.h5; on `workers` local
    processes or on the Ray cluster `ray_address`: :func:`pliant.reduction.snapshots.collect`),
    build the reduced model (:func:`build`, `options`) and save it as `folder`/reduced.npz."""
    folder = Path(folder)
    began = time.perf_counter()
    path = snap.collect(
        model,
        cases,
        folder / "snapshots.h5",
        dt=dt,
        every=every,
        workers=workers,
        ray_address=ray_address,
        progress=progress,
    )
    recorded = snap.load(path, model, [c.name for c in cases])
    positions = np.concatenate([p for _, p in recorded.values()])
    meta = {
        "dt": dt,
        "cases": [c.name for c in cases],
        "collect_seconds": time.perf_counter() - began,
    }
    reduced = build(model, positions, metadata=meta | options.pop("metadata", {}), **options)
    reduced.save(folder / "reduced.npz")
    return reduced


@dataclass(frozen=True, eq=False)
class RampedCommands:
    """Commands moving linearly from one level to the next over each `phase` seconds
    (starting from zero), then held: the environments' ramped actions. A value, so that a
    load case driven by it runs on another process."""

    levels: Sequence[np.ndarray]
    phase: float

    def __call__(self, t: float) -> np.ndarray:
        first = np.zeros_like(np.asarray(self.levels[0], dtype=float))
        points = [first, *map(np.asarray, self.levels)]
        k, frac = divmod(t / self.phase, 1.0)
        k = int(k)
        if k >= len(points) - 1:
            return points[-1].copy()
        return points[k] + frac * (points[k + 1] - points[k])


def multigait_cases(
    *,
    amplitude: tuple[float, float] = (4900.0, 3300.0),
    phase: float = 0.6,
    sequences: int = 3,
    cycles: int = 1,
    seed: int = 0,
) -> list[LoadCase]:
    """The Multigait's training load cases: the hand gait (`cycles` cycles), each symmetric
    group (rear pair, centre, front pair) inflated, held and deflated alone, and `sequences`
    random sequences of six of the environment's discrete actions (a group to its amplitude
    or to zero over a phase)."""
    groups = (("rear_left", "rear_right"), ("centre",), ("front_left", "front_right"))
    centre, leg = amplitude
    full = np.array([centre if c == "centre" else leg for c in CHAMBERS])
    masks = [np.isin(CHAMBERS, g).astype(float) for g in groups]
    cases = [
        LoadCase(
            "gait",
            functools.partial(demo_actuation, amplitude=amplitude, phase=phase),
            6 * phase * cycles,
        )
    ]
    for g, mask in zip(groups, masks, strict=True):
        level = mask * full
        cases.append(
            LoadCase(
                f"only_{g[0].split('_')[0]}",
                RampedCommands([level, level, 0 * level], phase),
                3 * phase,
            )
        )
    rng = np.random.default_rng(seed)
    for k in range(sequences):
        level, levels = np.zeros(len(CHAMBERS)), []
        for action in rng.integers(0, 6, size=6):
            mask = masks[action // 2]
            level = np.where(mask > 0, full if action % 2 == 0 else 0.0, level)
            levels.append(level.copy())
        cases.append(LoadCase(f"actions_{seed}_{k}", RampedCommands(levels, phase), 6 * phase))
    return cases


def robot_cases(entry, duration: float, phase: float) -> list[LoadCase]:
    """A robot's load cases: its scripted actuation over `duration`, then each actuator
    alone ramped to the largest command the script gives it, held and released (one
    `phase` each)."""
    probe = entry.demo_actuation(0.0)
    if not isinstance(probe, np.ndarray | list | tuple):
        raise PliantError(
            "this robot's scripted actuation is a control object, not commands: give its"
            " load cases through pliant.reduction.reduce"
        )
    times = np.linspace(0.0, duration, 200)
    peak = np.max(np.abs([np.asarray(entry.demo_actuation(t), dtype=float) for t in times]), axis=0)
    cases = [LoadCase("demo", entry.demo_actuation, duration)]
    for i, level in enumerate(peak):
        if level > 0:
            target = np.zeros_like(peak)
            target[i] = level
            cases.append(
                LoadCase(
                    f"actuator_{i}", RampedCommands([target, target, 0 * target], phase), 3 * phase
                )
            )
    return cases


def compare(model, reduced, entry, dt: float, seconds: float) -> dict:
    """Node-position error of the reduced model against the full FEM under the scripted
    actuation over `seconds` (model units), and the speed of both (steps/s)."""
    steps = max(1, round(seconds / dt))
    runs = {}
    for name, solver, state in (
        ("full", ImplicitEuler(model, dt), model.rest_state()),
        ("reduced", (s := reduced.solver(model, dt)), s.rest_state()),
    ):
        positions = []
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ContactConvergenceWarning)
            began = time.perf_counter()
            for _ in range(steps):
                state = solver.step(state, entry.demo_actuation(state.time))
                positions.append(np.array(state.positions))
            runs[name] = (np.array(positions), steps / (time.perf_counter() - began))
    error = np.linalg.norm(runs["reduced"][0] - runs["full"][0], axis=2)
    length = float(np.linalg.norm(np.ptp(model.body.rest_positions, axis=0)))
    return {
        "check_seconds": seconds,
        "max_error": float(error.max()),
        "rms_error": float(np.sqrt(np.mean(error**2))),
        "max_error_pct_size": 100 * float(error.max()) / length,
        "full_steps_per_s": runs["full"][1],
        "reduced_steps_per_s": runs["reduced"][1],
    }


def cache_folder() -> Path:
    """Where reduced models built on demand are kept: $PLIANT_CACHE/reduction, by default
    ~/.cache/pliant/reduction."""
    root = os.environ.get("PLIANT_CACHE") or Path.home() / ".cache" / "pliant"
    return Path(root) / "reduction"


def cached(
    model: Model,
    cases: Sequence[LoadCase],
    settings: dict,
    *,
    dt: float = 0.01,
    **options,
) -> ReducedModel:
    """The reduced model of `model` trained on `cases`, built once and then read from the
    cache (:func:`cache_folder`), under a name made of the mesh's fingerprint and a digest of
    `settings` (everything that makes the snapshots: the builder's arguments, the cases'
    parameters) and of `options` and `dt`."""
    key = json.dumps({**settings, **options, "dt": dt}, sort_keys=True, default=str)
    digest = hashlib.sha256(key.encode()).hexdigest()[:12]
    folder = cache_folder()
    path = folder / f"{model.name}_{mesh_fingerprint(model.body)}_{digest}.npz"
    if path.exists():
        return ReducedModel.load(path, model)
    with tempfile.TemporaryDirectory(dir=folder.parent if folder.exists() else None) as work:
        reduced = reduce(model, cases, work, dt=dt, metadata={"settings": key}, **options)
    folder.mkdir(parents=True, exist_ok=True)
    return ReducedModel.load(reduced.save(path), model)
