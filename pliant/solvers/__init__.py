"""Time steppers and static solvers, sharing ``step(state, control) -> state``, and the
stepper of a world of rigid bodies (``step(state) -> state``)."""

from pliant.solvers.batched import BatchedImplicitEuler
from pliant.solvers.implicit_euler import ImplicitEuler
from pliant.solvers.protocol import CondensingSolver, Solver
from pliant.solvers.rigid import RigidSolver, RigidState, RigidWorld
from pliant.solvers.static import StaticSolver
from pliant.solvers.system import LinearisedSystem

__all__ = [
    "BatchedImplicitEuler",
    "CondensingSolver",
    "ImplicitEuler",
    "LinearisedSystem",
    "RigidSolver",
    "RigidState",
    "Solver",
    "RigidWorld",
    "StaticSolver",
]
