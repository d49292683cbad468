"""Closed-loop control through the differentiable simulation: analytic policy gradients.

A policy (a torch module, say) reads the state at each control step and sets the actuator
commands; the commands ramp linearly from the last ones over `substeps` solver steps, as
Pliant's environments apply an action (:meth:`pliant.envs.base.SoftRobotEnv.step`). Each
solver step is :func:`pliant.diff.torch.step`, so a loss of the whole episode written in torch
back-propagates through time to the policy's parameters: each step's backward pass is its
adjoint (:class:`pliant.diff.step.StepAdjoint`, reusing the step's own factorisation), the
policy's is torch's. One episode costs its rollout and one adjoint sweep, whatever the number
of parameters: this is what a policy-gradient method such as PPO estimates from many
episodes' returns instead.

torch is needed (as for :mod:`pliant.diff.torch`).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import torch

from pliant.constraints.base import EmbeddedPoints
from pliant.diff import torch as diff_torch
from pliant.errors import ModelError
from pliant.model import Model, State
from pliant.solvers.implicit_euler import ImplicitEuler

#: policy(positions (n, 3), velocities (n, 3), control step) -> commands (n_a,), tensors.
Policy = Callable[[torch.Tensor, torch.Tensor, int], torch.Tensor]


def embedded_positions(points: EmbeddedPoints, positions: torch.Tensor) -> torch.Tensor:
    """(k, 3) positions of embedded points (barycentric in their elements) from the nodes'
    positions (n, 3), differentiable in them."""
    weights = torch.as_tensor(points.weights, dtype=positions.dtype, device=positions.device)
    nodes = torch.as_tensor(points.nodes, device=positions.device)
    return (weights[:, :, None] * positions[nodes]).sum(dim=1)


def closed_loop(
    model: Model,
    solver: ImplicitEuler,
    state0: State,
    policy: Policy,
    n_steps: int,
    *,
    substeps: int = 1,
    commands0: np.ndarray | None = None,
) -> list[tuple[torch.Tensor, torch.Tensor]]:
    """An episode of `n_steps` control steps from `state0`: at each, the policy's commands,
    reached by a linear ramp from the last ones (`commands0` at first, default zeros) over
    `substeps` solver steps. Returns the positions and velocities (n, 3) after each control
    step, `state0`'s first (n_steps + 1 pairs), differentiable with respect to whatever the
    policy's commands are (its parameters).

    Raises:
        ModelError: what :func:`pliant.diff.torch.step` refuses, or bad step counts."""
    if int(n_steps) != n_steps or n_steps < 1 or int(substeps) != substeps or substeps < 1:
        raise ModelError(
            f"closed_loop needs n_steps >= 1 and substeps >= 1, got {n_steps}, {substeps}"
        )
    like = dict(dtype=torch.float64)
    q = torch.as_tensor(state0.positions, **like)
    v = torch.as_tensor(state0.velocities, **like)
    last = torch.as_tensor(np.zeros(model.n_actuators) if commands0 is None else commands0, **like)
    states = [state0]  # each step's State: the next one's time, forces and displacements
    out = [(q, v)]
    for n in range(int(n_steps)):
        target = policy(q, v, n)
        for k in range(1, int(substeps) + 1):
            command = last + (target - last) * (k / substeps)
            q, v = diff_torch.step(model, solver, states[-1], command, q, v, states=states)
        last = target
        out.append((q, v))
    return out
