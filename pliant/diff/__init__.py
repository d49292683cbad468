"""Exact gradients through the FEM step: adjoints of the implicit Euler step and of the static
equilibrium, trajectory gradients with checkpointing, torch bindings (:mod:`pliant.diff.torch`).

See docs/diff.md for the method and what is held fixed.
"""

from pliant.diff.calibration import CalibrationResult, calibrate
from pliant.diff.losses import (
    ControlPenalty,
    Loss,
    Losses,
    PointTracking,
    StageGradient,
    StateCotangents,
)
from pliant.diff.parameters import element_young_poisson, set_parameters
from pliant.diff.rollout import RolloutGradient, rollout, rollout_gradient
from pliant.diff.static import static_gradient
from pliant.diff.step import PARAMETERS, StepAdjoint

__all__ = [
    "PARAMETERS",
    "CalibrationResult",
    "ControlPenalty",
    "Loss",
    "Losses",
    "PointTracking",
    "RolloutGradient",
    "StageGradient",
    "StateCotangents",
    "StepAdjoint",
    "calibrate",
    "element_young_poisson",
    "rollout",
    "rollout_gradient",
    "set_parameters",
    "static_gradient",
]
