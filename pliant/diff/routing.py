"""Cable routing as a design parameter: where each cable passes through the body.

A cable passes through points embedded in the body (:class:`pliant.constraints.base.
EmbeddedPoints`): point j lies in element e_j with barycentric weights w_j, and moves with
the body as p_j(x) = sum_a w_ja x_a. Its *routing point* is its rest position P_j, where it
sits in the undeformed body; the weights are the element's shape functions there,
w_ja = N_a(P_j), linear in P_j with gradient the element's rest shape-function gradient
g_a. So inside an element

    d p_j / d P_j = sum_a x_a (x) g_a = F_e(x),

the element's deformation gradient, and the cable's rest length L0 = L(P) moves with P too.
A routing point crossing a face into the next element keeps p_j continuous, but F changes:
the loss is piecewise smooth in P, with kinks on the element faces (one-sided derivatives
there).

The rows of cable c (:class:`pliant.constraints.cable.CableActuator`) are
delta_c(x; P) = L(P) - L(p(x; P)) and H_c(x; P) z = -sum_j dL/dp_j . z_j with
z_j = sum_a w_ja z_a. :func:`routing_gradient` gives the gradient in P of

    phi(P) = sum_c a_c delta_c(x; P) + sum_k sum_c b_kc H_c(x; P) z_k,

the only form in which the routing enters a step's or an equilibrium's residual (the adjoints
of :mod:`pliant.diff.step` and :mod:`pliant.diff.static` pass their own coefficients): with
F_j = F_e(x) and G_j = F_e(z),

    d phi / d P_j = a_c (dL/dV_j(P) - F_j^T dL/dp_j) - b_c (F_j^T (Hess L z~)_j + G_j^T dL/dp_j),

Hess L of the polyline length (segment by segment (I - u u^T) / l on the difference of its
end points' directions z~).
"""

from __future__ import annotations

import copy

import numpy as np

from pliant.constraints.base import EmbeddedPoints
from pliant.constraints.cable import CableActuator
from pliant.diff.elements import rest_shape
from pliant.errors import ModelError
from pliant.model import Model


def cable_indices(model: Model) -> list[int]:
    """Indices into ``model.actuators`` of its cables, whose routing :data:`"cable_routing"`
    differentiates (other actuators have none)."""
    return [i for i, a in enumerate(model.actuators) if isinstance(a, CableActuator)]


def routing_points(model: Model) -> np.ndarray:
    """(P, 3) the rest positions of every cable's points, cable after cable in actuator
    order: the layout of the ``"cable_routing"`` gradient."""
    rest = model.body.rest_positions
    parts = [model.actuators[i].points.positions(rest) for i in cable_indices(model)]
    return np.vstack(parts) if parts else np.zeros((0, 3))


def routing_slices(model: Model) -> dict[str, slice]:
    """Cable name -> its rows in :func:`routing_points`."""
    out, start = {}, 0
    for i in cable_indices(model):
        k = len(model.actuators[i].points)
        out[model.actuators[i].name] = slice(start, start + k)
        start += k
    return out


def rerouted(model: Model, points: np.ndarray) -> Model:
    """A model like `model` whose cables pass through the rest positions `points` (P, 3, as
    :func:`routing_points`), each embedded in the element of the rest mesh that holds it; the
    cables' rest lengths follow. The body, effectors and contacts are shared, not copied.

    Raises:
        ModelError: wrong shape, a point outside the body (beyond 1e-9 of its size).
    """
    body = model.body
    points = np.asarray(points, dtype=float)
    current = routing_points(model)
    if points.shape != current.shape or not np.all(np.isfinite(points)):
        raise ModelError(
            f"routing points must be finite {current.shape}, one per cable point, got"
            f" {points.shape}"
        )
    actuators = list(model.actuators)
    for name, rows in routing_slices(model).items():
        i = next(k for k, a in enumerate(actuators) if a.name == name)
        embedded = EmbeddedPoints(body.mesh, points[rows], tolerance=1e-9 * body.extent)
        cable = copy.copy(actuators[i])
        cable.points = embedded
        cable.rest_length = cable.length(body.rest_positions)
        actuators[i] = cable
    return Model(
        body,
        actuators=actuators,
        effectors=model.effectors,
        contacts=model.contacts,
        drivers=model.drivers,
        name=model.name,
    )


def _point_frames(points: EmbeddedPoints, rest: np.ndarray, y: np.ndarray) -> np.ndarray:
    """(k, 3, 3) F_j(y) = sum_a y_a (x) g_a of each point's element, g its rest shape-function
    gradients (so F_j(x) = d p_j / d P_j)."""
    ordered = np.sort(points.nodes, axis=1)
    if np.any(ordered[:, 1:] == ordered[:, :-1]):
        raise ModelError(
            "routing gradients need cable points embedded in elements (EmbeddedPoints(mesh,"
            " points)), not at nodes (EmbeddedPoints.at_nodes): a node's weights have no"
            " gradient"
        )
    grads = rest_shape(None, rest[points.nodes], None).grads
    return np.einsum("kai,kaj->kij", y[points.nodes], grads)


def _polyline_terms(cable: CableActuator, verts: np.ndarray, directions: np.ndarray | None):
    """dL/dV at the polyline `verts` (pull point first, if any) for the embedded points
    (k, 3), and, for `directions` z~ of the embedded points (k, 3), (Hess L z~) for them."""
    seg = np.diff(verts, axis=0)
    length = np.linalg.norm(seg, axis=1)
    if np.any(length == 0.0):
        raise ModelError(f"{cable.name}: two consecutive cable points coincide")
    unit = seg / length[:, None]
    dl = np.zeros_like(verts)
    dl[1:] += unit
    dl[:-1] -= unit
    start = 0 if cable.pull_point is None else 1
    if directions is None:
        return dl[start:], None
    z = np.zeros_like(verts)
    z[start:] = directions
    dz = np.diff(z, axis=0)
    r = (dz - unit * np.einsum("si,si->s", unit, dz)[:, None]) / length[:, None]
    hz = np.zeros_like(verts)
    hz[1:] += r
    hz[:-1] -= r
    return dl[start:], hz[start:]


def _vertices(cable: CableActuator, p: np.ndarray) -> np.ndarray:
    return p if cable.pull_point is None else np.vstack([cable.pull_point, p])


def routing_gradient(
    model: Model,
    x: np.ndarray,
    distance_coefficients: np.ndarray,
    products: list[tuple[np.ndarray, np.ndarray]] = (),
) -> np.ndarray:
    """(P, 3) gradient in the routing points of phi (module docstring) at positions `x`:
    `distance_coefficients` a (n_a,) multiply the rows' values, each (b, z) of `products`
    (b (n_a,), z (n, 3)) the rows' products H z. Coefficients of actuators other than cables
    are ignored."""
    rest = model.body.rest_positions
    out = []
    for i in cable_indices(model):
        cable = model.actuators[i]
        pts = cable.points
        p = pts.positions(x)
        f_x = _point_frames(pts, rest, x)
        dl_rest, _ = _polyline_terms(cable, _vertices(cable, pts.positions(rest)), None)
        grad = distance_coefficients[i] * dl_rest
        dl_now = None
        for b, z in products:
            if b[i] == 0.0:
                continue
            dl_now, hz = _polyline_terms(cable, _vertices(cable, p), pts.positions(z))
            f_z = _point_frames(pts, rest, z)
            grad -= b[i] * (np.einsum("kij,ki->kj", f_x, hz) + np.einsum("kij,ki->kj", f_z, dl_now))
        if distance_coefficients[i] != 0.0:
            if dl_now is None:
                dl_now, _ = _polyline_terms(cable, _vertices(cable, p), None)
            grad -= distance_coefficients[i] * np.einsum("kij,ki->kj", f_x, dl_now)
        out.append(grad)
    return np.vstack(out) if out else np.zeros((0, 3))
