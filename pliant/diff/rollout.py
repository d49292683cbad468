"""Gradients of a trajectory loss by a checkpointed reverse sweep of step adjoints.

Forward: T steps of the solver from s_0 under the controls, keeping every k-th state counted
back from the last (checkpoints: the first segment takes the remainder of T / k, the last,
kept from the forward pass, a whole k steps) and summing the loss's stage terms. Reverse:
segment by segment from the last, the segment's states are recomputed from its checkpoint
(the step is deterministic: the "fresh" policy refactorises each step), then each step's
adjoint (:class:`pliant.diff.step.StepAdjoint`: its linearisation and
factorisation, one block solve, the complex-step element terms) carries the cotangent of
s_{n+1} back to s_n and adds its parameters' share. With k ~ sqrt(T), 2 sqrt(T) states are
held at a time for 2 T - k forward steps in all; with k = T (the default for trajectories that
fit in memory), T states and T forward steps.

Each adjoint reuses its forward step's linearisation and factorisation ("fresh" factorises
A = a_m M + a_k K_s(q) at every step, the adjoint's own matrix): the solver hands each step's
factorisation over (:meth:`pliant.solvers.system.LinearisedSystem.hand_over`) while the
segment to be swept is stepped, forward or recomputed, and the adjoint then costs solves
rather than a factorisation. The factorisation objects are recycled across segments and calls
(per solver), so that no symbolic analysis is repeated. At most KEEP_FACTORS_BYTES of them are
held (rated at 4 doubles per entry of A's pattern each): where a segment's would not fit, the
latest steps' are kept (the sweep meets them first) and the earlier steps' adjoints
refactorise, into one reused object.
"""

from __future__ import annotations

import math
import weakref
from dataclasses import dataclass, field

import numpy as np

from pliant.constraints.control import DirectControl
from pliant.diff.losses import Loss, StageGradient
from pliant.diff.parameters import check_regions, region_sum
from pliant.diff.step import StepAdjoint, check_model, check_parameters
from pliant.errors import ModelError
from pliant.model import Model, State
from pliant.solvers.implicit_euler import ImplicitEuler
from pliant.solvers.linear import SparseCholesky, sparse_cholesky

#: A trajectory whose states take at most this is kept whole by default (no recomputation).
KEEP_ALL_BYTES = 256 * 2**20
#: The forward steps' factorisations of a segment are kept for its adjoints within this.
KEEP_FACTORS_BYTES = 256 * 2**20
# Factorisation objects handed over by each solver's system, for reuse (see _Tape).
_POOLS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


@dataclass
class RolloutGradient:
    """A loss and its gradients.

    Attributes:
        value: the loss.
        gradients: "initial_positions", "initial_velocities" (n, 3) and each name of `wrt`:
            "controls" (T, n_a); "young_modulus", "poisson_ratio" (float, or one per region);
            "density", "rayleigh_mass", "rayleigh_stiffness" (floats); "external_forces"
            (n, 3), a constant nodal force added at every step; "rest_positions" (n, 3).
        final: the last state of the rollout.
        states_held: the most states held at once (checkpoints and one segment).
        forward_steps: solver steps taken (forward and recomputation).
    """

    value: float
    gradients: dict[str, np.ndarray | float]
    final: State
    states_held: int = 0
    forward_steps: int = 0
    stage_values: list[float] = field(default_factory=list)


def check_solver(model: Model, solver) -> None:
    if not isinstance(solver, ImplicitEuler) or solver.model is not model:
        raise ModelError("rollout gradients need the model's ImplicitEuler (see static_gradient)")
    if solver.system.policy == "lagged":
        raise ModelError(
            "rollout gradients need ImplicitEuler(tangent='fresh'): the 'lagged' policy steps"
            " with an earlier step's tangent, not a function of the step's own state"
        )


def check_controls(model: Model, controls) -> np.ndarray:
    out = np.asarray(controls, dtype=float)
    if out.ndim != 2 or out.shape[1] != model.n_actuators or out.shape[0] < 1:
        raise ModelError(
            f"controls must be (T, {model.n_actuators}) commands, one row per step, got {out.shape}"
        )
    if not np.all(np.isfinite(out)):
        raise ModelError("controls must be finite")
    return out


def rollout(model: Model, solver, state0: State, controls: np.ndarray) -> list[State]:
    """The states s_0 .. s_T of the solver under the controls (one command row per step)."""
    controls = check_controls(model, controls)
    states = [state0]
    for c in controls:
        states.append(solver.step(states[-1], DirectControl(c.copy())))
    return states


def rollout_gradient(
    model: Model,
    solver: ImplicitEuler,
    state0: State,
    controls: np.ndarray,
    loss: Loss,
    *,
    wrt: tuple[str, ...] | str = ("controls",),
    checkpoint_every: int | None = None,
    regions: np.ndarray | None = None,
) -> RolloutGradient:
    """The loss of the rollout from `state0` under `controls` (T, n_a) and its gradients.

    Args:
        model: the robot (tetrahedral body, actuators, contacts at their forward states:
            see docs/diff.md).
        solver: its ImplicitEuler, ``tangent="fresh"``.
        state0: the initial state.
        controls: one row of actuator commands per step, in the actuators' modes.
        loss: stage terms (:mod:`pliant.diff.losses`).
        wrt: parameters (:data:`pliant.diff.step.PARAMETERS`).
        checkpoint_every: keep every k-th state in the forward pass and recompute the
            segments between them (k ~ sqrt(T) holds 2 sqrt(T) states for 2 T steps). Default:
            every state when the trajectory takes at most KEEP_ALL_BYTES (256 MiB; 1000
            steps of the Trunk take 32 MB), else ceil(sqrt(T)).
        regions: element -> region index, for E and nu per region (default: the body's).

    Raises:
        ModelError: unsupported model or solver, unknown parameter, wrong shapes.
    """
    check_model(model)
    check_solver(model, solver)
    names = check_parameters(wrt)
    regions = check_regions(model, regions)
    controls = check_controls(model, controls)
    state0 = model.check_state(state0)
    n_steps = controls.shape[0]
    state_bytes = 2 * state0.positions.nbytes
    if checkpoint_every is not None:
        k = checkpoint_every
    elif (n_steps + 1) * state_bytes <= KEEP_ALL_BYTES:
        k = n_steps  # every state kept from the forward pass: nothing recomputed
    else:
        k = max(1, math.ceil(math.sqrt(n_steps)))
    if int(k) != k or k < 1:
        raise ModelError(f"checkpoint_every must be a positive integer, got {k!r}")
    saved = [a.value for a in model.actuators]
    k = int(k)
    factor_bytes = 4 * 8 * model.body.pattern.indices.size
    tape = _Tape(solver, capacity=KEEP_FACTORS_BYTES // factor_bytes)
    try:
        return _sweep(model, solver, tape, state0, controls, loss, names, k, regions)
    finally:
        tape.clear()
        for a, v in zip(model.actuators, saved, strict=True):
            a.value = v


def take_factorisation(solver: ImplicitEuler) -> SparseCholesky:
    """The factorisation of the solver's last step, handed over (its system factorises the
    next step into a recycled object): for that step's :class:`StepAdjoint`. Give it back
    with :func:`recycle_factorisation` once the adjoint is done with it."""
    pool = _POOLS.setdefault(solver.system, [])
    return solver.system.hand_over(pool.pop() if pool else None)


def recycle_factorisation(solver: ImplicitEuler, factor: SparseCholesky) -> None:
    """A factorisation taken by :func:`take_factorisation`, free for the solver's next steps."""
    _POOLS.setdefault(solver.system, []).append(factor)


class _Tape:
    """The linearisations and factorisations of the latest steps of the segment to be swept
    (module docstring), by step index, `capacity` of them at most."""

    def __init__(self, solver: ImplicitEuler, capacity: int) -> None:
        self.solver, self.system, self.capacity = solver, solver.system, capacity
        self.pool: list[SparseCholesky] = _POOLS.setdefault(self.system, [])
        self.steps: dict[int, tuple] = {}

    def record(self, n: int) -> None:
        """Take step n's linearisation and factorisation (call right after the step)."""
        if self.capacity < 1:
            return
        if len(self.steps) >= self.capacity:  # the earliest kept step's adjoint refactorises
            self.pool.append(self.steps.pop(min(self.steps))[1])
        self.steps[n] = (self.system.lin, take_factorisation(self.solver))

    def take(self, n: int) -> dict:
        """StepAdjoint's keywords for step n: its records, or a workspace to factorise into."""
        if n in self.steps:
            lin, factor = self.steps.pop(n)
            self.pool.append(factor)  # free again once this step's adjoint is done
            return {"linearisation": lin, "factor": factor}
        if not self.pool:
            body = self.system.body
            self.pool.append(sparse_cholesky(body.pattern.indptr, body.pattern.indices))
        return {"workspace": self.pool[-1]}

    def clear(self) -> None:
        self.pool.extend(factor for _, factor in self.steps.values())
        self.steps.clear()


def _sweep(model, solver, tape, state0, controls, loss, names, k, regions) -> RolloutGradient:
    n_steps = controls.shape[0]
    checkpoints = {0: state0.copy()}
    stage_values = [loss.stage(0, state0, None).value]
    state = state0
    tail = [state0]  # the states since the last checkpoint: the last segment, not recomputed
    for n in range(n_steps):
        state = solver.step(state, DirectControl(controls[n].copy()))
        tape.record(n)
        stage_values.append(loss.stage(n + 1, state, controls[n]).value)
        tail.append(state)
        if (n_steps - n - 1) % k == 0 and n + 1 < n_steps:
            checkpoints[n + 1] = state.copy()
            tail = [checkpoints[n + 1]]
            tape.clear()
    final = state
    steps = n_steps
    n_nodes = model.body.n_nodes
    dq, dv = np.zeros((n_nodes, 3)), np.zeros((n_nodes, 3))
    grads: dict[str, np.ndarray | float] = {}
    per_element: dict[str, np.ndarray] = {}
    control_grad = np.zeros_like(controls)
    held = len(checkpoints)
    starts = sorted(checkpoints)
    for start, stop in reversed(list(zip(starts, [*starts[1:], n_steps], strict=True))):
        segment, tail = (tail, None) if tail is not None else ([checkpoints[start]], None)
        for n in range(start + len(segment) - 1, stop):
            segment.append(solver.step(segment[-1], DirectControl(controls[n].copy())))
            tape.record(n)
            steps += 1
        held = max(held, len(checkpoints) + len(segment))
        for n in range(stop - 1, start - 1, -1):
            new = segment[n + 1 - start]
            _add_stage(loss.stage(n + 1, new, controls[n]), dq, dv, control_grad, n)
            adjoint = StepAdjoint(
                model, solver.dt, segment[n - start], controls[n], new, **tape.take(n)
            )
            out = adjoint.vjp(dq, dv, tuple(names))
            dq, dv = out.pop("positions"), out.pop("velocities")
            for name, value in out.items():
                if name == "controls":
                    control_grad[n] += value
                elif name in ("young_modulus", "poisson_ratio"):
                    per_element[name] = per_element.get(name, 0.0) + value
                else:
                    grads[name] = grads.get(name, 0.0) + value
    first = loss.stage(0, state0, None)
    _add_stage(first, dq, dv, None, 0)
    grads["initial_positions"], grads["initial_velocities"] = dq, dv
    if "controls" in names:
        grads["controls"] = control_grad
    for name, values in per_element.items():
        grads[name] = region_sum(values, regions)
    return RolloutGradient(float(np.sum(stage_values)), grads, final, held, steps, stage_values)


def _add_stage(part: StageGradient, dq, dv, control_grad, n) -> None:
    if part.positions is not None:
        dq += part.positions
    if part.velocities is not None:
        dv += part.velocities
    if part.control is not None and control_grad is not None:
        control_grad[n] += part.control
