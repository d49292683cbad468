"""Pieces shared by the robot builders."""

from __future__ import annotations

import dataclasses

import numpy as np

from pliant.constraints.base import EmbeddedPoints
from pliant.constraints.cable import CableActuator
from pliant.constraints.cavity import CavityActuator
from pliant.constraints.effector import PositionEffector
from pliant.constraints.friction import ContactForces
from pliant.errors import ModelError
from pliant.fem.body import TetBody, nodes_in_box
from pliant.mesh.quality import validate_mesh
from pliant.mesh.tetmesh import TetMesh
from pliant.model import Model, State
from pliant.robots.parameters import Cables


def fixed_by_box(mesh: TetMesh, box: np.ndarray) -> np.ndarray:
    # A mesh passed by the user is checked before its nodes are selected, so that an empty or
    # broken mesh reports what is wrong with it rather than an empty fixing box.
    validate_mesh(mesh.points, mesh.tets)
    nodes = nodes_in_box(mesh.points, box)
    if nodes.size == 0:
        raise ModelError(f"the fixing box {np.asarray(box).tolist()} holds no node of the mesh")
    return nodes


def landmark(mesh: TetMesh, name: str, default: np.ndarray | list) -> np.ndarray:
    """A landmark of a parametric mesh, or the reference scene's value for a loaded mesh."""
    return np.atleast_2d(np.asarray(mesh.landmarks.get(name, default), dtype=float))


def cables(
    mesh: TetMesh,
    body: TetBody,
    paths: list[np.ndarray],
    pull_points: list[np.ndarray],
    limits: Cables,
    max_displacement: list[float] | float,
    *,
    names: list[str] | None = None,
) -> list[CableActuator]:
    """A cable along each path from its pull point (None: from its first point), named
    `names` (default cable_<i>), with the `limits` and `max_displacement` (mm, one for all or
    one per cable)."""
    maxd = np.broadcast_to(np.asarray(max_displacement, dtype=float), (len(paths),))
    names = names if names is not None else [f"cable_{i}" for i in range(len(paths))]
    return [
        CableActuator(
            EmbeddedPoints(mesh, path),
            body.rest_positions,
            pull_point=pull,
            name=names[i],
            mode=limits.cable_mode,
            min_force=0.0,
            max_force=limits.max_cable_force,
            max_displacement=float(maxd[i]),
            max_displacement_change=limits.max_displacement_change,
        )
        for i, (path, pull) in enumerate(zip(paths, pull_points, strict=True))
    ]


def cavity(
    mesh: TetMesh, body: TetBody, surface: str, *, max_pressure: float, **bounds
) -> CavityActuator:
    """A cavity actuator of the mesh's `surface` (name: the surface's), bounded by
    `max_pressure` (kPa), in force (pressure) mode unless `bounds` say otherwise."""
    bounds = {"name": surface, "mode": "force", **bounds}
    return CavityActuator(
        mesh.surfaces[surface], body.rest_positions, max_force=max_pressure, **bounds
    )


CAVITY_MODES = {"pressure": "force", "volume": "displacement"}


def cavity_mode(name: str) -> str:
    """The actuator mode of a cavity commanded by "pressure" (kPa) or "volume" (mm^3)."""
    if name not in CAVITY_MODES:
        raise ModelError(f"cavity_mode must be 'pressure' or 'volume', got {name!r}")
    return CAVITY_MODES[name]


def effector(
    mesh: TetMesh, body: TetBody, point: np.ndarray, name: str = "effector"
) -> PositionEffector:
    return PositionEffector(EmbeddedPoints(mesh, point), body.rest_positions, name=name)


def fingertips(mesh: TetMesh, body: TetBody, points: list[np.ndarray]) -> list[PositionEffector]:
    """An effector at each point, named fingertip_<i>."""
    return [effector(mesh, body, p, f"fingertip_{i}") for i, p in enumerate(points)]


def curling(n: int, tip: tuple[float, float, float], drop: float, inward: float) -> np.ndarray:
    """n goals along the arc of a fingertip curling down from `tip` by `drop` (mm) in z,
    drawing in along x by `inward` * drop at the end (inverse control trajectories)."""
    a = np.linspace(0.0, 1.0, n)
    x0, y0, z0 = tip
    return np.column_stack([x0 - inward * drop * a**2, np.full(n, y0), z0 - drop * a])


def smooth_ramp(t: float, start: float, duration: float) -> float:
    """0 before `start`, 1 after `start + duration`, the cubic smoothstep 3s^2 - 2s^3 between
    (zero velocity at both ends): how scripted carts and bases move."""
    s = min(max((t - start) / duration, 0.0), 1.0)
    return s * s * (3.0 - 2.0 * s)


def settled(model: Model, sim, steps: int) -> State:
    """The rest state after `steps` unactuated steps, its clock back at 0 (the ramps start
    there): positions, velocities and rigid bodies, without the contact warm start."""
    state = model.rest_state()
    for _ in range(steps):
        state = sim.step(state, np.zeros(len(model.actuators)))
    cleared = {"contact_forces": ContactForces.empty(), "displacement_before": np.zeros(0)}
    return dataclasses.replace(state, time=0.0, step=0, layout=None, **cleared)
