"""torch bindings: a step and a whole rollout as ``torch.autograd.Function``s.

A loss written in torch (a network's output fed as the cable commands, a policy, a fitted
material) back-propagates through the simulation: the forward pass runs the solver in NumPy,
the backward pass hands the incoming cotangents to the adjoints of :mod:`pliant.diff`
(:class:`~pliant.diff.step.StepAdjoint`, :func:`~pliant.diff.rollout.rollout_gradient`), in
float64. The rollout's backward pass runs the trajectory again (checkpointed), so a rollout
costs its forward pass plus one gradient. torch is an optional dependency: importing this
module needs it.
"""

from __future__ import annotations

import weakref

import numpy as np
import torch

from pliant.constraints.base import EmbeddedPoints
from pliant.constraints.control import DirectControl
from pliant.diff.losses import StateCotangents
from pliant.diff.parameters import set_parameters
from pliant.diff.rollout import (
    check_controls,
    check_solver,
    recycle_factorisation,
    rollout_gradient,
    take_factorisation,
)
from pliant.diff.step import StepAdjoint, check_model
from pliant.errors import ModelError
from pliant.model import Model, State
from pliant.solvers.implicit_euler import ImplicitEuler

#: The scalar parameters a torch rollout takes as tensors.
TORCH_PARAMETERS = ("young_modulus", "poisson_ratio", "rayleigh_mass", "rayleigh_stiffness")


def _numpy(t: torch.Tensor) -> np.ndarray:
    return t.detach().cpu().to(torch.float64).numpy()


class _Step(torch.autograd.Function):
    @staticmethod
    def forward(ctx, positions, velocities, commands, model, solver, state, states):
        start = state.copy()
        start.positions, start.velocities = _numpy(positions), _numpy(velocities)
        c = _numpy(commands)
        new = solver.step(start, DirectControl(c.copy()))
        # The step's own linearisation and factorisation serve its adjoint; the factorisation
        # goes back to the solver when the graph lets the adjoint go.
        factor = take_factorisation(solver)
        ctx.adjoint = StepAdjoint(
            model, solver.dt, start, c, new, linearisation=solver.system.lin, factor=factor
        )
        weakref.finalize(ctx.adjoint, recycle_factorisation, solver, factor)
        if states is not None:
            states.append(new)
        like = dict(dtype=torch.float64, device=positions.device)
        return torch.as_tensor(new.positions, **like), torch.as_tensor(new.velocities, **like)

    @staticmethod
    def backward(ctx, dq, dv):
        out = ctx.adjoint.vjp(_numpy(dq), _numpy(dv), ("controls",))
        like = dict(dtype=dq.dtype, device=dq.device)
        return (
            torch.as_tensor(out["positions"], **like),
            torch.as_tensor(out["velocities"], **like),
            torch.as_tensor(out["controls"], **like),
            None,
            None,
            None,
            None,
        )


def step(
    model: Model,
    solver: ImplicitEuler,
    state: State,
    commands: torch.Tensor,
    positions: torch.Tensor | None = None,
    velocities: torch.Tensor | None = None,
    *,
    states: list[State] | None = None,
) -> tuple[torch.Tensor, torch.Tensor]:
    """One step from `state` (its positions and velocities replaced by the tensors, when
    given) under `commands` (n_a,): the new positions and velocities (n, 3), differentiable
    with respect to the three tensors. The solver is the model's ImplicitEuler with
    ``tangent="fresh"``. With `states`, the State the step returned is appended to it (the
    next step's start: its time, actuator forces and displacements)."""
    check_model(model)
    check_solver(model, solver)
    like = dict(dtype=torch.float64)
    q = torch.as_tensor(state.positions, **like) if positions is None else positions
    v = torch.as_tensor(state.velocities, **like) if velocities is None else velocities
    return _Step.apply(q, v, commands, model, solver, state, states)


class _Rollout(torch.autograd.Function):
    @staticmethod
    def forward(ctx, controls, parameters, names, model, solver, state0, points, every):
        values = dict(zip(names, _numpy(parameters), strict=True))
        set_parameters(model, **values)
        c = check_controls(model, _numpy(controls))
        states, state = [state0.positions], state0
        for row in c:
            state = solver.step(state, DirectControl(row.copy()))
            states.append(state.positions)
        ctx.saved = (c, values, names, model, solver, state0, points, every)
        out = np.stack(states)
        if points is not None:
            out = np.stack([points.positions(x) for x in states])
        return torch.as_tensor(out, dtype=torch.float64, device=controls.device)

    @staticmethod
    def backward(ctx, grad):
        c, values, names, model, solver, state0, points, every = ctx.saved
        set_parameters(model, **values)
        loss = StateCotangents(_numpy(grad), points=points)
        wrt = ("controls", *names)
        result = rollout_gradient(model, solver, state0, c, loss, wrt=wrt, checkpoint_every=every)
        like = dict(dtype=grad.dtype, device=grad.device)
        params = torch.as_tensor([result.gradients[n] for n in names], **like)
        return (torch.as_tensor(result.gradients["controls"], **like), params) + (None,) * 6


def rollout(
    model: Model,
    solver: ImplicitEuler,
    state0: State,
    controls: torch.Tensor,
    *,
    parameters: dict[str, torch.Tensor] | None = None,
    points: EmbeddedPoints | None = None,
    checkpoint_every: int | None = None,
) -> torch.Tensor:
    """Positions of the rollout from `state0` under `controls` (T, n_a): (T + 1, n, 3), or
    the points' (T + 1, k, 3) with `points` (an effector's, say); differentiable with
    respect to the controls and to `parameters`, scalar tensors named in
    :data:`TORCH_PARAMETERS` (set on the model, in place, as the rollout runs).

    Raises:
        ModelError: unsupported model, solver or parameter; wrong shapes."""
    check_model(model)
    parameters = parameters or {}
    unknown = [n for n in parameters if n not in TORCH_PARAMETERS]
    if unknown:
        raise ModelError(f"torch rollouts take parameters {TORCH_PARAMETERS}, got {unknown}")
    names = tuple(parameters)
    stacked = (
        torch.stack(
            [torch.as_tensor(parameters[n], dtype=torch.float64).reshape(()) for n in names]
        )
        if names
        else torch.zeros(0, dtype=torch.float64)
    )
    return _Rollout.apply(controls, stacked, names, model, solver, state0, points, checkpoint_every)
