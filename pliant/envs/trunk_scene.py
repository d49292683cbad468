"""What the Trunk's object tasks (TrunkCup, TrunkPush, TrunkSpaceDebris) read from their
scenes: the neutral fibre, and the settled start state with its rigid bodies."""

from __future__ import annotations

import numpy as np

from pliant.constraints.base import EmbeddedPoints
from pliant.envs.trunk import LENGTH
from pliant.model import Model, State


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


def neutral_fibre(model: Model, n_points: int) -> EmbeddedPoints:
    """`n_points` points along the Trunk's axis (x = y = 0, z from 0 to its length), embedded
    in its mesh: the neutral fibre the observations read (as TrunkEnv's)."""
    z = np.linspace(0.0, LENGTH, n_points)
    axis = np.column_stack([np.zeros(n_points), np.zeros(n_points), z])
    return EmbeddedPoints(model.body.mesh, axis)
