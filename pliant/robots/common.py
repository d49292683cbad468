"""Pieces shared by the robot builders."""

from __future__ import annotations

from typing import Literal

import numpy as np

from pliant.constraints.base import EmbeddedPoints
from pliant.constraints.cable import CableActuator
from pliant.constraints.effector import PositionEffector
from pliant.errors import ModelError
from pliant.fem.body import TetBody, nodes_in_box
from pliant.fem.material import MATERIALS, Corotational, Material
from pliant.mesh.quality import validate_mesh
from pliant.mesh.tetmesh import TetMesh
from pliant.model import Model, State

MaterialName = Literal[
    "corotational", "corotational-large", "corotational-large-tolerant", "neo-hookean"
]

# Variants of the corotational law by name: SOFA's "large" element frames, and the same
# frames with inverted elements kept in the step, as SOFA runs them (see `Corotational`).
_VARIANTS = {
    "corotational-large": {"rotation": "large"},
    "corotational-large-tolerant": {"rotation": "large", "inversion": "tolerate"},
}


def make_material(name: str, young_modulus: float, poisson_ratio: float) -> Material:
    if name in _VARIANTS:
        return Corotational(young_modulus, poisson_ratio, **_VARIANTS[name])
    try:
        cls = MATERIALS[name]
    except KeyError:
        names = sorted([*MATERIALS, *_VARIANTS])
        raise ModelError(f"unknown material {name!r}; choose one of {names}") from None
    return cls(young_modulus, poisson_ratio)


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
    *,
    mode: str,
    max_displacement: list[float] | float,
    max_displacement_change: float | None,
    max_force: float,
) -> list[CableActuator]:
    maxd = np.broadcast_to(np.asarray(max_displacement, dtype=float), (len(paths),))
    return [
        CableActuator(
            EmbeddedPoints(mesh, path),
            body.rest_positions,
            pull_point=pull,
            name=f"cable_{i}",
            mode=mode,
            min_force=0.0,
            max_force=max_force,
            max_displacement=float(maxd[i]),
            max_displacement_change=max_displacement_change,
        )
        for i, (path, pull) in enumerate(zip(paths, pull_points, strict=True))
    ]


def effector(mesh: TetMesh, body: TetBody, point: np.ndarray) -> PositionEffector:
    return PositionEffector(EmbeddedPoints(mesh, point), body.rest_positions, name="effector")


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
    return State(
        state.positions,
        state.velocities,
        displacement=state.displacement,
        actuation=state.actuation,
        rigid_positions=state.rigid_positions,
        rigid_rotations=state.rigid_rotations,
        rigid_velocities=state.rigid_velocities,
        rigid_angular_velocities=state.rigid_angular_velocities,
    )
