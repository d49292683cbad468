"""Model order reduction: snapshots of the full FEM, a POD basis, hyper-reduction by ECSW and
the reduced step (thesis §3.1.2, §3.4.1; Goury and Duriez 2018).

    cases = multigait_cases()                          # load cases of the full model
    reduced = reduce(model, cases, "out/multigait")    # snapshots.h5 and reduced.npz there
    solver = reduced.solver(model, dt=0.01)            # same step(state, control) interface
    state = solver.step(solver.rest_state(), commands)
"""

from pliant.reduction import snapshots
from pliant.reduction.basis import ReducedBasis, full_basis, mesh_fingerprint, pod
from pliant.reduction.ecsw import IntegrationDomain, Selection, greedy_nnls, hyper_reduce
from pliant.reduction.pipeline import build, multigait_cases, reduce
from pliant.reduction.reduced import ReducedModel
from pliant.reduction.snapshots import LoadCase
from pliant.reduction.solver import ReducedImplicitEuler, ReducedState

__all__ = [
    "IntegrationDomain",
    "LoadCase",
    "ReducedBasis",
    "ReducedImplicitEuler",
    "ReducedModel",
    "ReducedState",
    "Selection",
    "build",
    "full_basis",
    "greedy_nnls",
    "hyper_reduce",
    "mesh_fingerprint",
    "multigait_cases",
    "pod",
    "reduce",
    "snapshots",
]
