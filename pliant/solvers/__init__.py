"""Time steppers and static solvers, sharing ``step(state, control) -> state``."""

from pliant.solvers.batched import BatchedImplicitEuler
from pliant.solvers.implicit_euler import ImplicitEuler
from pliant.solvers.static import StaticSolver
from pliant.solvers.system import LinearisedSystem

__all__ = ["BatchedImplicitEuler", "ImplicitEuler", "LinearisedSystem", "StaticSolver"]
