"""Hyper-reduction by energy-conserving sampling and weighting (ECSW; Farhat, Avery, Chapman
and Cortial, IJNME 98(9), 2014), as the ModelOrderReduction plugin applies it to soft robots.

The reduced internal force is a sum over the elements, f_r(alpha) = sum_e Phi_e^T f_e(q_e);
ECSW replaces it by a weighted sum over a few of them, the reduced integration domain (RID),
sum_{e in RID} xi_e Phi_e^T f_e(q_e), xi_e >= 0. For training configurations q_s, the column
of element e stacks its contributions g_se = Phi_e^T f_e(q_s) over the snapshots (rows: s x
modes), b = G 1 is the exact reduced force, and the weights solve

    min |G xi - b|  subject to xi >= 0,  stopped once |G xi - b| <= tau |b|,

by Lawson and Hanson's active-set NNLS taken greedily: add the element whose column most
reduces the residual, solve the least squares on the chosen set, step back to drop weights
that turn negative. The weights are non-negative, so the weighted tangent stays a sum of the
elements' tangents, and the reduced forces stay conservative. Tetrahedra and each membrane's
triangles are selected separately, each with its own tolerance (SofaGym's Multigait: 0.03 and
0.05).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg

from pliant.errors import ReductionError
from pliant.fem import kernels
from pliant.reduction.basis import ReducedBasis, check_snapshots, check_tolerance


@dataclass(frozen=True)
class Selection:
    """Elements of one set (tetrahedra, or a membrane's triangles) and their weights.

    Attributes:
        elements: indices of the selected elements.
        weights: xi_e > 0 of each.
        error: |G xi - b| / |b| on the training snapshots (0 for the whole set).
    """

    elements: np.ndarray
    weights: np.ndarray
    error: float = 0.0

    @classmethod
    def everything(cls, n: int) -> Selection:
        return cls(np.arange(n), np.ones(n), 0.0)


@dataclass(frozen=True)
class IntegrationDomain:
    """The reduced integration domain: selected tetrahedra and membrane triangles."""

    tets: Selection
    membranes: tuple[Selection, ...] = ()

    @classmethod
    def everything(cls, body) -> IntegrationDomain:
        """Every element with weight 1: the exact reduced forces."""
        return cls(
            Selection.everything(body.n_elements),
            tuple(Selection.everything(len(a.membrane.triangles)) for a in body.membranes),
        )


def tet_contributions(body, basis: ReducedBasis, positions: np.ndarray) -> np.ndarray:
    """(s, r, m) Phi_e^T f_e(q_s) of every tetrahedron at each configuration (s, n, 3)."""
    m, r = body.n_elements, basis.n_modes
    phi = basis.modes[body.tets].reshape(m, 12, r)
    out = np.empty((len(positions), r, m))
    forces = np.empty((m, 4, 3))
    frames, dets = np.empty((m, 3, 3)), np.empty(m)
    for s, x in enumerate(positions):
        kernels.internal_forces(
            np.ascontiguousarray(x),
            np.empty((0, 3)),
            body.tets,
            body.grads,
            body.volumes,
            body.mu,
            body.lam,
            body.material.kernel_tag,
            body.frame_nodes,
            body.rest_frames,
            forces,
            np.empty((0, 4, 3)),
            frames,
            dets,
        )
        if not dets.min() > 0.0:
            raise ReductionError(
                f"training configuration {s} has inverted elements: the snapshots or their"
                " projection on the basis are not admissible (add modes)"
            )
        out[s] = np.einsum("mk,mkr->rm", forces.reshape(m, 12), phi)
    return out


def membrane_contributions(membrane, basis: ReducedBasis, positions: np.ndarray) -> np.ndarray:
    """(s, r, t) Phi_e^T f_e(q_s) of every triangle of `membrane`."""
    t, r = len(membrane.triangles), basis.n_modes
    phi = basis.modes[membrane.triangles].reshape(t, 9, r)
    out = np.empty((len(positions), r, t))
    for s, x in enumerate(positions):
        forces, _ = membrane.element_forces(x)
        out[s] = np.einsum("tk,tkr->rt", forces.reshape(t, 9), phi)
    return out


def greedy_nnls(
    g: np.ndarray, b: np.ndarray, tolerance: float, *, max_elements: int | None = None
) -> Selection:
    """Non-negative weights xi on few columns of G with |G xi - b| <= tolerance |b| (module
    docstring). ReductionError when `max_elements` columns do not reach the tolerance."""
    tolerance = check_tolerance("the ECSW tolerance tau", tolerance)
    n = g.shape[1]
    limit = n if max_elements is None else min(n, int(max_elements))
    b_norm = float(np.linalg.norm(b))
    if b_norm == 0.0:
        raise ReductionError("the training snapshots give no internal force to fit")
    chosen: list[int] = []
    excluded = np.zeros(n, dtype=bool)
    xi = np.zeros(0)
    gram = np.zeros((0, 0))  # G_Z^T G_Z of the chosen columns, kept as they change
    rhs = np.zeros(0)  # G_Z^T b
    residual = b.copy()
    while np.linalg.norm(residual) > tolerance * b_norm:
        if len(chosen) >= limit:
            raise ReductionError(
                f"ECSW reached {limit} elements at a relative error"
                f" {np.linalg.norm(residual) / b_norm:.3g} > tau = {tolerance}: raise tau or"
                " the element budget"
            )
        score = g.T @ residual
        score[chosen] = -np.inf
        score[excluded] = -np.inf
        j = int(np.argmax(score))
        if not score[j] > 0.0:
            break  # no column lowers the residual any further: the NNLS optimum
        column = g[:, j]
        cross = g[:, chosen].T @ column
        gram = np.block([[gram, cross[:, None]], [cross[None, :], column @ column]])
        rhs = np.append(rhs, column @ b)
        chosen.append(j)
        xi = np.append(xi, 0.0)
        while True:
            z = _solve_gram(gram, rhs)
            if np.all(z > 0.0):
                xi = z
                break
            negative = z <= 0.0
            if negative[-1] and xi[-1] == 0.0 and np.all(z[:-1] > 0.0):
                # The new column cannot take a positive weight (round-off): leave it out.
                excluded[j] = True
                keep = np.arange(len(chosen) - 1)
            else:
                step = np.min(xi[negative] / (xi[negative] - z[negative]))
                xi = xi + step * (z - xi)
                keep = np.flatnonzero(xi > 1e-14 * max(1.0, float(np.abs(xi).max())))
            chosen = [chosen[k] for k in keep]
            xi, gram, rhs = xi[keep], gram[np.ix_(keep, keep)], rhs[keep]
            if not chosen:
                break
        residual = b - g[:, chosen] @ xi if chosen else b.copy()
    order = np.argsort(chosen)
    return Selection(
        np.asarray(chosen, dtype=np.int64)[order],
        xi[order],
        float(np.linalg.norm(residual) / b_norm),
    )


def _solve_gram(gram: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """Least-squares weights on the chosen columns from their normal equations."""
    try:
        return scipy.linalg.solve(gram, rhs, assume_a="pos")
    except (np.linalg.LinAlgError, scipy.linalg.LinAlgError):
        return np.linalg.lstsq(gram, rhs, rcond=None)[0]


def hyper_reduce(
    body,
    basis: ReducedBasis,
    positions: np.ndarray,
    *,
    tau: float = 0.03,
    tau_membrane: float = 0.05,
    max_elements: int | None = None,
) -> IntegrationDomain:
    """The RID of `body` for `basis`, trained on configurations (s, n, 3) (SofaGym's
    Multigait: tau 0.03 for the tetrahedra, 0.05 for the paper membrane)."""
    basis.check(body)
    tau = check_tolerance("the ECSW tolerance tau", tau)
    tau_membrane = check_tolerance("the membrane's ECSW tolerance", tau_membrane)
    q = check_snapshots(positions, body.n_nodes)

    def select(contributions: np.ndarray, tolerance: float) -> Selection:
        s, r, m = contributions.shape
        g = contributions.reshape(s * r, m)
        return greedy_nnls(g, g.sum(axis=1), tolerance, max_elements=max_elements)

    tets = select(tet_contributions(body, basis, q), tau)
    membranes = tuple(
        select(membrane_contributions(a.membrane, basis, q), tau_membrane) for a in body.membranes
    )
    return IntegrationDomain(tets, membranes)
