"""Trajectory optimisation with condensed FEM dynamics (thesis §5.2): box-DDP whose forward
pass is the full FEM and whose backward pass runs on the effectors' condensed dynamics."""

from pliant.trajopt.ddp import BoxDDP, DDPResult
from pliant.trajopt.dynamics import CondensedDynamics, ForceControl, Rollout
from pliant.trajopt.linear import LinearDynamics
from pliant.trajopt.mpc import CondensedMPC, MPCResult
from pliant.trajopt.problem import ActuationBounds, QuadraticCost, tracking_cost

__all__ = [
    "ActuationBounds",
    "BoxDDP",
    "CondensedDynamics",
    "CondensedMPC",
    "DDPResult",
    "ForceControl",
    "LinearDynamics",
    "MPCResult",
    "QuadraticCost",
    "Rollout",
    "tracking_cost",
]
