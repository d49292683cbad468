"""Mechanics from predicted condensed matrices, differentiable (torch), batched over samples.

These are the quantities the thesis builds its calibration and design objectives from
(§5.1.6): the effector displacement reached for imposed actuator displacements (Eq. 5.16) and
the force on a blocked contact point (Eq. 5.18). All take W (n, rows, rows) and delta_free
(n, rows) in a layout's row order, as :class:`~pliant.condensed.layout.Layout` slices them.
"""

from __future__ import annotations

import torch
from torch import Tensor


def symmetric(w_triangle: Tensor, n_rows: int) -> Tensor:
    """W (..., n_rows, n_rows) from its upper triangle, diagonal included, row-major (the
    order of numpy.triu_indices that Layout.pack uses)."""
    rows, cols = torch.triu_indices(n_rows, n_rows)
    w = w_triangle.new_zeros((*w_triangle.shape[:-1], n_rows, n_rows))
    w[..., rows, cols] = w_triangle
    w[..., cols, rows] = w_triangle
    return w


def effector_displacement(
    w: Tensor, free: Tensor, delta_a: Tensor, actuators: slice, effectors: slice
) -> Tensor:
    """Eq. 5.16: delta_e = W_ea W_aa^-1 (delta_a - delta_a_free) + delta_e_free, the effector
    rows reached when the actuators are at displacements delta_a (n, a), no contact."""
    w_ea, w_aa = w[:, effectors, actuators], w[:, actuators, actuators]
    forces = torch.linalg.solve(w_aa, (delta_a - free[:, actuators]).unsqueeze(-1))
    return (w_ea @ forces).squeeze(-1) + free[:, effectors]


def blocked_force(
    w: Tensor,
    free: Tensor,
    delta_a: Tensor,
    actuators: slice,
    contacts: slice,
    held: Tensor | None = None,
) -> Tensor:
    """Eq. 5.18: the force lambda_c on contact rows held at `held` (default 0, the object does
    not move) while the actuators are at displacements delta_a:

        lambda_c = B^-1 [W_ca W_aa^-1 (delta_a - delta_a_free) + delta_c_free - held],
        B = W_ca W_aa^-1 W_ac - W_cc,

    from delta_a = W_aa lambda_a + W_ac lambda_c + delta_a_free and the same for delta_c
    (Eq. 2.14). Any rows of the layout can stand for the contact, e.g. a fingertip effector.
    """
    w_aa = w[:, actuators, actuators]
    w_ca, w_cc = w[:, contacts, actuators], w[:, contacts, contacts]
    w_aa_inv_ac = torch.linalg.solve(w_aa, w_ca.transpose(1, 2))
    b = w_ca @ w_aa_inv_ac - w_cc
    pulled = torch.linalg.solve(w_aa, (delta_a - free[:, actuators]).unsqueeze(-1))
    rhs = (w_ca @ pulled).squeeze(-1) + free[:, contacts]
    if held is not None:
        rhs = rhs - held
    return torch.linalg.solve(b, rhs.unsqueeze(-1)).squeeze(-1)
