"""Exact gradients through the FEM step: adjoints of the implicit Euler step and of the static
equilibrium, trajectory gradients with checkpointing, calibration and control by L-BFGS-B,
torch bindings (:mod:`pliant.diff.torch`).

See docs/diff.md for the method and what is held fixed.
"""

from pliant.diff.calibration import CalibrationResult, calibrate
from pliant.diff.control import ControlResult, actuator_box, optimise_controls
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
    "ControlResult",
    "Loss",
    "Losses",
    "PointTracking",
    "RolloutGradient",
    "StageGradient",
    "StateCotangents",
    "StepAdjoint",
    "actuator_box",
    "calibrate",
    "element_young_poisson",
    "optimise_controls",
    "rollout",
    "rollout_gradient",
    "set_parameters",
    "static_gradient",
]
