"""What a solver is: the interface controllers, environments, planners and learners rely on.

Every stepper of a model takes a state and the actuators' commands (None: keep the model's)
and returns the next state: the full FEM ones (:class:`~pliant.solvers.ImplicitEuler`,
:class:`~pliant.solvers.StaticSolver`), the reduced one
(:class:`pliant.reduction.ReducedImplicitEuler`), a proxy's
(:class:`pliant.proxy.actuation.ProxySolver`) and a SOFA scene's with its controllers
(:class:`pliant.sofa.loader.ControlledSolver`). Those that hold the step's factorisation also
give the constraint-space problem of a state (``condense``: the compliance W and the free
displacements), which inverse control and trajectory optimisation read. Batched and
rigid-body steppers (``BatchedImplicitEuler``, ``RigidSolver``) step other things and are not
solvers of one model in this sense.
"""

from __future__ import annotations

from typing import Any, Protocol, runtime_checkable

__all__ = ["CondensingSolver", "Solver"]


@runtime_checkable
class Solver(Protocol):
    """``step(state, control=None) -> state`` on ``model``."""

    model: Any

    def step(self, state: Any, control: Any = None) -> Any: ...


@runtime_checkable
class CondensingSolver(Solver, Protocol):
    """A solver that also gives a state's constraint-space problem (``W``, ``delta_free``)."""

    def condense(self, state: Any) -> Any: ...
