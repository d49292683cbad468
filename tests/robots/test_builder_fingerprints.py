"""Every registered robot, built with its defaults, is the model it was when the builders were
written out one by one (before the shared parameter groups of issue #59): the same nodes,
elements, per-element material, masses, actuators, effectors, rigid bodies, contacts and
drivers, and the same state after one implicit step under its scripted actuation.

The fixture data/builder_fingerprints.json holds, per robot, a fingerprint of its model:
scalars as they are and each array as its shape and two projections (its sum, and its dot
product with a fixed pseudo-random vector, which tells a reordering). Regenerate it from a
tree whose builders are known good with
``PYTHONPATH=. python tests/robots/test_builder_fingerprints.py --write``.
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np
import pytest

from pliant import robots
from pliant.solvers import ImplicitEuler

FIXTURE = Path(__file__).parent / "data" / "builder_fingerprints.json"
DT = 0.01
T_CONTROL = 0.5  # the scripted actuation's time used for the step's control

# What the fingerprint reads of the model's parts: plain attributes of these kinds. Not a
# collision shape's bounding-volume hierarchy (``_bvh``): derived from its triangles (which are
# read), and its node layout follows numpy's argpartition among equal centroids, which numpy
# 2.4 orders otherwise than the numpy the fixture was written with (the mazes' walls).
_NOT_READ = {"_bvh"}
_SKIP = {"mesh", "body", "rod", "carrier", "shape_cache", "_cache", "model", *_NOT_READ}


def _project(array: np.ndarray) -> list:
    a = np.asarray(array)
    if a.dtype == bool:
        a = a.astype(np.int64)
    if a.dtype.kind not in "fiu" or a.size == 0:
        return [list(a.shape)]
    flat = a.astype(np.float64).ravel()
    weights = np.random.default_rng(12345).uniform(0.5, 1.5, flat.size)
    return [list(a.shape), float(flat.sum()), float(flat @ weights)]


def _value(v, depth: int):
    if v is None or isinstance(v, (bool, str)):
        return v
    if isinstance(v, (int, np.integer)):
        return int(v)
    if isinstance(v, (float, np.floating)):
        return float(v) if math.isfinite(v) else str(float(v))
    if isinstance(v, np.ndarray):
        return _project(v)
    if isinstance(v, (list, tuple)):
        items = [_value(x, depth) for x in v]
        if items and all(isinstance(x, (int, float)) for x in items):
            return _project(np.asarray(v, dtype=float))
        return [x for x in items if x is not _NOTHING]
    if depth > 0 and hasattr(v, "__dict__") and type(v).__module__.startswith("pliant"):
        return _attributes(v, depth - 1)
    return _NOTHING


_NOTHING = object()


def _attributes(obj, depth: int = 1) -> dict:
    out = {"type": type(obj).__name__}
    for key in sorted(vars(obj)):
        if key in _SKIP:
            continue
        v = _value(getattr(obj, key), depth)
        if v is not _NOTHING:
            out[key] = v
    return out


def fingerprint(name: str) -> dict:
    entry = robots.entry(name)
    model = entry.build()
    body = model.body
    print_body = {
        key: _project(getattr(body, key))
        for key in (
            "rest_positions",
            "tets",
            "elements",
            "mu",
            "lam",
            "node_masses",
            "fixed_nodes",
            "fixed_dofs",
            "gravity",
            "young_moduli",
            "densities",
        )
        if isinstance(getattr(body, key, None), np.ndarray)
    }
    for key in ("rayleigh_mass", "rayleigh_stiffness", "lag_tolerance"):
        if hasattr(body, key):
            print_body[key] = _value(getattr(body, key), 0)
    print_body["material"] = _attributes(body.material, 0) if hasattr(body, "material") else None
    parts = {
        "actuators": [_attributes(a) for a in model.actuators],
        "effectors": [_attributes(e) for e in model.effectors],
        "rigid_bodies": [_attributes(r) for r in model.rigid_bodies],
        "drivers": [_attributes(d) for d in model.drivers],
        "contacts": _attributes(model.contacts) if model.contacts is not None else None,
    }
    control = entry.demo_actuation(T_CONTROL)
    state = ImplicitEuler(model, dt=DT).step(model.rest_state(), control)
    step = {
        key: _project(getattr(state, key))
        for key in ("positions", "velocities", "rigid_positions", "rigid_velocities")
        if getattr(state, key, None) is not None
    }
    step["actuation"] = _project(state.actuation)
    return {"name": model.name, "body": print_body, **parts, "step": step}


# Attributes added since the fixture was written, with the value that leaves a model as it was
# (a rigid body's held twist components; a triangle mesh's winding-number inside and per-face
# sphere contacts; the contacts' resting points): a model that has them at these values is the
# fingerprinted one.
_ADDED = {"held": None, "per_face": False, "winding": False, "resting": None}


def _compare(expected, got, path: str, rtol: float) -> list[str]:
    if isinstance(expected, dict):  # the fixture reads parts no longer read (the BVHs)
        expected = {k: v for k, v in expected.items() if k not in _NOT_READ}
    if isinstance(expected, dict) and isinstance(got, dict):
        added = [k for k in set(got) - set(expected) if k in _ADDED]
        changed = [f"{path}.{k}: {got[k]!r} != {_ADDED[k]!r}" for k in added if got[k] != _ADDED[k]]
        if changed:
            return changed
        got = {k: v for k, v in got.items() if k not in added}
    if isinstance(expected, dict):
        if not isinstance(got, dict) or set(expected) != set(got):
            keys = sorted(got) if isinstance(got, dict) else got
            return [f"{path}: keys {sorted(expected)} != {keys!r}"]
        return [d for k in expected for d in _compare(expected[k], got[k], f"{path}.{k}", rtol)]
    if isinstance(expected, list):
        if not isinstance(got, list) or len(expected) != len(got):
            return [f"{path}: {expected!r} != {got!r}"]
        return [
            d
            for i, (e, g) in enumerate(zip(expected, got, strict=True))
            for d in _compare(e, g, f"{path}[{i}]", rtol)
        ]
    if isinstance(expected, float) and isinstance(got, (int, float)):
        if math.isclose(expected, got, rel_tol=rtol, abs_tol=1e-300):
            return []
        return [f"{path}: {expected!r} != {got!r}"]
    return [] if expected == got else [f"{path}: {expected!r} != {got!r}"]


def _fixture() -> dict:
    if not FIXTURE.exists():
        pytest.skip(f"{FIXTURE} is missing (write it with --write from a known-good tree)")
    return json.loads(FIXTURE.read_text())


@pytest.mark.parametrize("name", sorted(robots.ROBOTS))
def test_builder_fingerprint_is_unchanged(name: str) -> None:
    """The model and its first step: exact to round-off (rel 1e-12) for what is built, 1e-9
    for the step (iterative solves)."""
    expected = _fixture()[name]
    got = json.loads(json.dumps(fingerprint(name)))
    step = _compare(expected.pop("step"), got.pop("step"), f"{name}.step", 1e-9)
    built = _compare(expected, got, name, 1e-12)
    assert not built + step, "\n".join((built + step)[:20])


def test_every_registered_robot_has_a_fingerprint() -> None:
    assert sorted(_fixture()) == sorted(robots.ROBOTS)


if __name__ == "__main__" and "--write" in sys.argv:
    FIXTURE.parent.mkdir(exist_ok=True)
    data = {name: fingerprint(name) for name in sorted(robots.ROBOTS)}
    FIXTURE.write_text(json.dumps(data, indent=1, sort_keys=True) + "\n")
    print(f"wrote {FIXTURE} ({FIXTURE.stat().st_size} bytes)")
