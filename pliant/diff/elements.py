"""Element forces and tangent products in NumPy, complex-step safe, for the adjoints.

The compiled kernels (:mod:`pliant.fem.kernels`) give one configuration's forces and K_s w; an
adjoint also needs their derivatives with respect to the nodes' positions, the rest shape and
the material. These functions are the same formulas written with operations that are analytic
(no ``abs``, no SVD, no conjugate), vectorised over elements, so that a complex-step
perturbation x + i h e_j gives d/dx_j of any smooth output as Im(out) / h, exact to round-off
(Squire & Trapp 1998; no step to tune, no cancellation):

* polar rotation R of F = R S: Higham's Newton iteration X <- (z X + X^-T / z) / 2 run to
  round-off (z = det(X)^(-1/3), scaling the first iterations), and for a complex F its exact
  first variation (what the complex step of the iteration converges to);
* SOFA's "large" rotation R = Q(x) Q(X)^T from the edge frames, norms as sqrt(sum of squares);
* Neo-Hookean P = mu (F - F^-T) + lam ln J F^-T.

Forces are f_a = -V P(F) g_a and tangent products (K_s w)_a = V dP(dF) g_a with
dF = sum_a w_a (x) g_a and the tangent the solvers assemble (corotational: SOFA's
R (2 mu sym(R^T dF) + lam tr(R^T dF) I); Neo-Hookean: its exact tangent). The tests check
both against the compiled kernels to round-off.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pliant.errors import ModelError
from pliant.fem.body import TetBody
from pliant.fem.material import (
    COROTATIONAL,
    COROTATIONAL_LARGE,
    COROTATIONAL_LARGE_INVERTIBLE,
    NEO_HOOKEAN,
)

#: Complex-step size: far below round-off of any coordinate, so Re(out) is out itself.
COMPLEX_STEP = 1e-30


@dataclass(frozen=True)
class ElementShape:
    """An element set's rest-shape quantities: gradients g (m, 4, 3), signed volumes (m,),
    rest edge frames Q(X) (m, 3, 3) (large rotation only), possibly complex."""

    grads: np.ndarray
    volumes: np.ndarray
    rest_frames: np.ndarray | None


def rest_shape(body: TetBody, rest: np.ndarray, frame_local: np.ndarray | None) -> ElementShape:
    """Rest gradients, volumes and frames of the elements whose rest corners are `rest`
    (m, 4, 3): the kernel's :func:`~pliant.fem.kernels.rest_gradients` in analytic form."""
    dm = np.swapaxes(rest[..., 1:, :] - rest[..., :1, :], -1, -2)  # columns X_k - X_0
    dm_inv = np.swapaxes(inv3_transposed(dm)[0], -1, -2)
    grads = np.concatenate([-dm_inv.sum(axis=-2, keepdims=True), dm_inv], axis=-2)
    volumes = det3(dm) / 6.0
    frames = None if frame_local is None else edge_frames(rest, frame_local)
    return ElementShape(grads, volumes, frames)


def body_shape(body: TetBody) -> ElementShape:
    """The body's own rest quantities (as its kernels read them)."""
    large = body.rest_frames.shape[0] > 0
    return ElementShape(body.grads, body.volumes, body.rest_frames if large else None)


def frame_local_nodes(body: TetBody) -> np.ndarray | None:
    """For the large rotation, the local index (0-3) in each element of its frame nodes."""
    if body.material.kernel_tag not in (COROTATIONAL_LARGE, COROTATIONAL_LARGE_INVERTIBLE):
        return None
    match = body.frame_nodes[:, :, None] == body.tets[:, None, :]
    return np.argmax(match, axis=2)


def check_material(body: TetBody) -> None:
    tag = body.material.kernel_tag
    if tag not in (COROTATIONAL, COROTATIONAL_LARGE, COROTATIONAL_LARGE_INVERTIBLE, NEO_HOOKEAN):
        raise ModelError(
            f"pliant.diff differentiates the corotational and Neo-Hookean laws, got {body.material}"
        )


def edge_frames(x: np.ndarray, local: np.ndarray) -> np.ndarray:
    """Edge frames Q (..., m, 3, 3) of the corners `x` (..., m, 4, 3), first three nodes
    `local` (m, 3)."""
    a, b, c = (
        np.take_along_axis(x, np.broadcast_to(local[:, k, None, None], (*x.shape[:-2], 1, 3)), -2)[
            ..., 0, :
        ]
        for k in range(3)
    )
    u, w = b - a, c - a
    n = np.cross(u, w)
    u = u / np.sqrt(np.sum(u * u, axis=-1))[..., None]
    n = n / np.sqrt(np.sum(n * n, axis=-1))[..., None]
    return np.stack([u, np.cross(n, u), n], axis=-1)


def det3(a: np.ndarray) -> np.ndarray:
    """det of each 3x3 matrix (..., 3, 3), written out (LAPACK's batched call costs more)."""
    return (
        a[..., 0, 0] * (a[..., 1, 1] * a[..., 2, 2] - a[..., 1, 2] * a[..., 2, 1])
        - a[..., 0, 1] * (a[..., 1, 0] * a[..., 2, 2] - a[..., 1, 2] * a[..., 2, 0])
        + a[..., 0, 2] * (a[..., 1, 0] * a[..., 2, 1] - a[..., 1, 1] * a[..., 2, 0])
    )


def inv3_transposed(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(a^-T, det a) for each 3x3 matrix: the cofactor matrix over the determinant."""
    cof = np.cross(a[..., [1, 2, 0], :], a[..., [2, 0, 1], :])  # rows: a_1 x a_2, ...
    det = np.einsum("...j,...j->...", a[..., 0, :], cof[..., 0, :])
    return cof / det[..., None, None], det


def polar_rotations(f: np.ndarray) -> np.ndarray:
    """R of F = R S for each F (..., 3, 3). Real part: scaled Newton iterations to round-off.
    A complex F = F_r + i dF (a complex step) gets R + i dR with the exact first variation
    dR = R [w]x, (tr(S) I - S) w = axial(R^T dF - dF^T R) (the kernels' exact tangent), which
    is what the complex step of the iteration converges to, for one solve instead of the
    iterations in complex arithmetic."""
    r = np.ascontiguousarray(f.real)
    settled = 0
    for _ in range(60):
        inv_t, det = inv3_transposed(r)
        scale = np.where(np.abs(det - 1.0) > 0.05, np.cbrt(det) ** -1.0, 1.0)[..., None, None]
        nxt = 0.5 * (scale * r + inv_t / scale)
        change = float(np.max(np.abs(nxt - r), initial=0.0))
        r = nxt
        settled = settled + 1 if change < 1e-14 else 0
        if settled == 2:
            break
    if not np.iscomplexobj(f):
        return r
    rt = np.swapaxes(r, -1, -2)
    w1 = rt @ f.imag
    s = rt @ f.real
    axial = np.stack(
        [
            w1[..., 2, 1] - w1[..., 1, 2],
            w1[..., 0, 2] - w1[..., 2, 0],
            w1[..., 1, 0] - w1[..., 0, 1],
        ],
        axis=-1,
    )
    m = np.trace(s, axis1=-2, axis2=-1)[..., None, None] * np.eye(3) - s
    w = np.linalg.solve(m, axial[..., None])[..., 0]
    skew = np.zeros(w.shape[:-1] + (3, 3))
    skew[..., 0, 1], skew[..., 0, 2], skew[..., 1, 2] = -w[..., 2], w[..., 1], -w[..., 0]
    skew[..., 1, 0], skew[..., 2, 0], skew[..., 2, 1] = w[..., 2], -w[..., 1], w[..., 0]
    return r + 1j * (r @ skew)


def element_terms(
    body: TetBody,
    x: np.ndarray,
    w: np.ndarray | None,
    shape: ElementShape,
    frame_local: np.ndarray | None,
    mu: np.ndarray,
    lam: np.ndarray,
) -> tuple[np.ndarray, np.ndarray | None]:
    """Element forces f_e (..., m, 4, 3) and tangent products (K_s w)_e (None without `w`)
    at corners `x` (..., m, 4, 3) (leading dimensions: a batch of configurations), for Lamé
    parameters `mu`, `lam` (m,). Inactive elements (det F <= 0, unless the law tolerates
    inversion) contribute nothing, as in the kernels."""
    tag = body.material.kernel_tag
    g, vol = shape.grads, shape.volumes
    f = np.einsum("...ai,...aj->...ij", x, g)
    det = det3(f)
    active = (det.real > 0.0) | (tag == COROTATIONAL_LARGE_INVERTIBLE)
    eye = np.eye(3)
    mu_, lam_ = mu[..., None, None], lam[..., None, None]
    if tag == NEO_HOOKEAN:
        safe = np.where(active[..., None, None], f, eye)
        finv_t = inv3_transposed(safe)[0]
        finv = np.swapaxes(finv_t, -1, -2)
        lnj = np.log(np.where(active, det, 1.0))[..., None, None]
        p = mu_ * safe + (lam_ * lnj - mu_) * finv_t
    else:
        if tag == COROTATIONAL:
            r = polar_rotations(np.where(active[..., None, None], f, eye))
        else:
            r = edge_frames(x, frame_local) @ np.swapaxes(shape.rest_frames, -1, -2)
        s = np.swapaxes(r, -1, -2) @ f
        eps = 0.5 * (s + np.swapaxes(s, -1, -2)) - eye
        tr = np.trace(eps, axis1=-2, axis2=-1)[..., None, None]
        p = r @ (2.0 * mu_ * eps + lam_ * tr * eye)
    forces = -vol[..., None, None] * np.einsum("...ij,...aj->...ai", p, g)
    forces = np.where(active[..., None, None], forces, 0.0)
    if w is None:
        return forces, None
    df = np.einsum("...ai,...aj->...ij", w, g)
    if tag == NEO_HOOKEAN:
        tr = np.einsum("...ik,...ki->...", finv, df)[..., None, None]
        dp = (
            mu_ * df
            + (mu_ - lam_ * lnj) * finv_t @ np.swapaxes(df, -1, -2) @ finv_t
            + lam_ * tr * finv_t
        )
    else:
        w1 = np.swapaxes(r, -1, -2) @ df
        tr = np.trace(w1, axis1=-2, axis2=-1)[..., None, None]
        dp = r @ (mu_ * (w1 + np.swapaxes(w1, -1, -2)) + lam_ * tr * eye)
    kw = vol[..., None, None] * np.einsum("...ij,...aj->...ai", dp, g)
    return forces, np.where(active[..., None, None], kw, 0.0)


def _perturbed(x: np.ndarray) -> np.ndarray:
    """The 12 complex-step perturbations of every element's corners at once: (12, m, 4, 3),
    entry j moving local coordinate j of every element by i h."""
    xc = np.broadcast_to(x, (12, *x.shape)).astype(complex)
    for j in range(12):
        xc[j, :, j // 3, j % 3] += 1j * COMPLEX_STEP
    return xc


def complex_step_gradient(function, x: np.ndarray) -> np.ndarray:
    """Gradient (m, 4, 3) of a per-element scalar `function(x) -> (..., m)` of the corners
    `x` (m, 4, 3): one batched evaluation of the 12 complex-step perturbations (each element's
    value depends on its own corners only)."""
    values = function(_perturbed(x)).imag / COMPLEX_STEP  # (12, m)
    return np.moveaxis(values, 0, -1).reshape(x.shape)


def complex_step_jacobian(function, x: np.ndarray) -> np.ndarray:
    """Jacobian blocks (m, 12, 12) of per-element outputs `function(x) -> (..., m, 4, 3)`."""
    m = x.shape[0]
    values = function(_perturbed(x)).imag.reshape(12, m, 12) / COMPLEX_STEP
    return np.moveaxis(values, 0, -1)


def nodal_sum(body: TetBody, element_values: np.ndarray) -> np.ndarray:
    """Sum element-node values (m, 4, 3) onto the nodes (n, 3)."""
    nodes = body.tets.ravel()
    values = element_values.reshape(-1, 3)
    return np.column_stack([np.bincount(nodes, values[:, i], body.n_nodes) for i in range(3)])
