"""Exceptions raised by Pliant.

Every error names what is wrong and why, so that a user never has to chase a NaN.
"""

from __future__ import annotations


class PliantError(Exception):
    """Base class of every error Pliant raises on purpose."""


class MeshError(PliantError, ValueError):
    """A mesh cannot be used for simulation (malformed, degenerate, inverted, disconnected)."""


class DegenerateElementError(MeshError):
    """An element has (near) zero volume."""


class InvertedElementError(MeshError):
    """An element has negative signed volume."""


class DisconnectedMeshError(MeshError):
    """The mesh has several connected components."""


class MeshFileError(MeshError):
    """A mesh file is missing, unreadable or holds no tetrahedra."""


class MeshingError(MeshError):
    """gmsh could not mesh a parametric shape (also with the fallback surface algorithms)."""


class StateError(PliantError, ValueError):
    """A state does not belong to the model it is used with (node count, array shapes, actuator
    or rigid-body counts), holds non-finite values, or its file cannot be read or written."""


class MaterialError(PliantError, ValueError):
    """Invalid material parameters (E <= 0, nu outside [0, 0.5), density <= 0, NaN)."""


class ModelError(PliantError, ValueError):
    """Invalid model construction (bad indices, empty selections, unknown names)."""


class ConstraintError(PliantError, ValueError):
    """Invalid constraint definition or bounds."""


class ContactError(PliantError, ValueError):
    """Invalid contact input: collision shape, friction coefficient, contact problem."""


class ContactConvergenceWarning(UserWarning):
    """The frictional contact solver stopped at max_iterations above its tolerance."""


class ContactMarginWarning(UserWarning):
    """A colliding point moved further than the contact margin in one step: contacts with
    obstacles it was not given rows for may have been missed."""


class InfeasibleProblemError(PliantError):
    """The bounds of a direct or inverse problem admit no solution."""


class SolverError(PliantError, RuntimeError):
    """A linear or nonlinear solve failed, or a solver was given invalid settings."""


class UnreachableGoalWarning(UserWarning):
    """Inverse control could not bring the effectors to their goals within the actuators'
    bounds: the actuation applied is the closest reachable one (least squares)."""


class InverseConvergenceWarning(UserWarning):
    """A static step's feedback control (inverse control) and the equilibrium did not converge
    together: the actuators were held where the last iteration put them, a best effort."""


class DivergenceError(PliantError, RuntimeError):
    """The simulation diverged: non-finite state, inverted elements, energy blow-up.

    Attributes:
        step: index of the step at which divergence was detected.
        cause: short machine-readable cause ("non-finite", "inverted", "energy", "solver").
    """

    def __init__(self, message: str, *, step: int, cause: str) -> None:
        super().__init__(message)
        self.step = step
        self.cause = cause


class TrainingError(PliantError, ValueError):
    """A training run is given invalid settings, or cannot go on: its loss became non-finite."""


class UnknownRobotError(PliantError, KeyError):
    """No robot builder is registered under this name."""

    def __str__(self) -> str:  # KeyError quotes its argument; keep the sentence readable
        return str(self.args[0]) if self.args else ""


class DatasetError(PliantError, ValueError):
    """A condensed-model dataset is corrupt, incomplete or incompatible with what uses it, or a
    partial collection was started with other settings."""


class WorkerError(PliantError, RuntimeError):
    """A worker process of a long job died (killed, out of memory); what it finished is kept
    and the same call resumes."""


class ThreadSettingError(PliantError, ValueError):
    """A thread setting given to :func:`pliant.configure_threads` is not one it knows."""


class LearnedModelError(PliantError, ValueError):
    """A learned condensed model cannot be used: unreadable file, or a robot whose constraint
    layout (actuators, effectors, contacts and their rows) differs from the one it learned."""


class PolicyError(PliantError, ValueError):
    """A policy cannot be kept or used: an algorithm, policy or space the kept format does not
    hold, or an observation of another shape than the policy's (or not finite)."""


class PlanningError(PliantError, ValueError):
    """A planner cannot be used on this environment or with these settings: no discrete actions,
    no get_state/set_state, a reward outside what the algorithm assumes, a budget too small."""


class TrajectoryOptimisationError(PliantError, ValueError):
    """An optimal control problem is ill-posed (horizon, weights, shapes) or its solve failed
    to produce a trajectory (a diverging rollout from the initial guess)."""


class ReductionError(PliantError, ValueError):
    """A reduced model cannot be built or used: snapshots with NaN, a basis or reduced model
    that does not match the model's mesh, a tolerance outside its range."""


class CorruptFileError(PliantError, ValueError):
    """A file Pliant wrote and reads back is empty, truncated, corrupt or not of its kind (a
    checkpoint, a saved model, a dataset); the message names the file and what is wrong."""

    def __init__(self, message: str, path=None) -> None:
        super().__init__(message)
        self.path = path


class MissingDependencyError(PliantError, ImportError):
    """An optional dependency a feature needs is not installed (Ray for its workers and Tune
    sweeps); the message names the package and how to install it."""


class CheckpointWarning(UserWarning):
    """A damaged checkpoint was skipped: the run resumes from an older intact one (named)."""
