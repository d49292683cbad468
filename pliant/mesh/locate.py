"""Embedding points in a tetrahedral mesh: containing element and barycentric coordinates.

Cable paths, effectors and contact points are carried by the mesh through these coordinates:
x = sum_i b_i p_i over the four nodes p_i of the containing tetrahedron.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from scipy.spatial import cKDTree

from pliant.errors import ModelError
from pliant.mesh.tetmesh import TetMesh

# Number of nearest element centroids tried before searching every element.
_CANDIDATES = 16
# Barycentric coordinates down to -_INSIDE_EPS count as inside (points on faces and edges).
_INSIDE_EPS = 1e-10


def barycentric_coordinates(mesh: TetMesh, tets: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Barycentric coordinates of points[j] in element tets[j], shape (k, 4).

    Solves [p1 - p0, p2 - p0, p3 - p0] (b1, b2, b3) = x - p0 and b0 = 1 - b1 - b2 - b3.
    """
    p = mesh.points[mesh.tets[tets]]
    edges = np.stack([p[:, 1] - p[:, 0], p[:, 2] - p[:, 0], p[:, 3] - p[:, 0]], axis=-1)
    b = np.linalg.solve(edges, (points - p[:, 0])[..., None])[..., 0]
    return np.concatenate([1.0 - b.sum(axis=1, keepdims=True), b], axis=1)


def _clamped(bary: np.ndarray) -> np.ndarray:
    """Project barycentric coordinates onto the element: negative parts to 0, sum back to 1."""
    b = np.clip(bary, 0.0, None)
    return b / b.sum(axis=-1, keepdims=True)


def locate_points(
    mesh: TetMesh,
    points: np.ndarray,
    *,
    tolerance: float | None = None,
    outside: Literal["project", "keep"] = "project",
) -> tuple[np.ndarray, np.ndarray]:
    """Find the tetrahedron containing each point and its barycentric coordinates.

    A point outside the mesh but within `tolerance` of it (a point on a curved surface that the
    mesh approximates by flat faces, say) is attached in one of two ways:

    * ``outside="project"``: to the nearest element found, with its barycentric coordinates
      clamped onto that element (the point moves onto the mesh);
    * ``outside="keep"``: as SOFA's BarycentricMapping does, to the element whose centre is
      nearest, with the point's own barycentric coordinates in it (some negative), so that
      the point stays where it is and follows that element's affine motion.

    Args:
        mesh: the mesh.
        points: (k, 3) or (3,) query points.
        tolerance: largest accepted distance outside the mesh; by default 1e-3 times the
            bounding-box diagonal of the mesh.
        outside: how a point outside the mesh is attached, see above.

    Returns:
        (k,) element indices and (k, 4) barycentric coordinates summing to 1, non-negative
        unless `outside` is "keep".

    Raises:
        ModelError: a point is non-finite or farther than `tolerance` outside the mesh.
    """
    points = np.atleast_2d(np.asarray(points, dtype=np.float64))
    if points.ndim != 2 or points.shape[1] != 3:
        raise ModelError(f"points must have shape (k, 3), got {points.shape}")
    if not np.isfinite(points).all():
        raise ModelError("points to locate must be finite")
    if tolerance is None:
        tolerance = 1e-3 * float(np.linalg.norm(np.ptp(mesh.points, axis=0)))
    if outside not in ("project", "keep"):
        raise ModelError(f"outside must be 'project' or 'keep', got {outside!r}")

    k = points.shape[0]
    if k == 0:
        return np.zeros(0, dtype=np.int64), np.zeros((0, 4))

    centroids = mesh.points[mesh.tets].mean(axis=1)
    tree = cKDTree(centroids)
    n_candidates = min(_CANDIDATES, mesh.n_tets)
    _, candidates = tree.query(points, k=n_candidates)
    candidates = candidates.reshape(k, n_candidates)
    candidate_bary = barycentric_coordinates(
        mesh, candidates.ravel(), np.repeat(points, n_candidates, axis=0)
    ).reshape(k, n_candidates, 4)
    best = np.argmax(candidate_bary.min(axis=2), axis=1)
    element = candidates[np.arange(k), best]
    bary = candidate_bary[np.arange(k), best]
    # The nearest centroids may miss the container in stretched meshes: search every element
    # that may hold the point or be nearest to it (as a search of all of them would).
    misses = np.flatnonzero(bary.min(axis=1) < -_INSIDE_EPS)
    if misses.size:
        reach = float(np.linalg.norm(mesh.points[mesh.tets] - centroids[:, None], axis=2).max())
        for j in misses:
            element[j], bary[j] = _search(mesh, tree, reach, points[j], candidates[j])

    out = bary.min(axis=1) < -_INSIDE_EPS
    projected = np.einsum("ki,kij->kj", _clamped(bary), mesh.points[mesh.tets[element]])
    distance = np.linalg.norm(projected - points, axis=1)
    if outside == "project":
        bary[out] = _clamped(bary[out])
    elif out.any():
        _, nearest = cKDTree(centroids).query(points[out])
        element[out] = nearest
        bary[out] = barycentric_coordinates(mesh, nearest, points[out])
    too_far = np.flatnonzero(distance > tolerance)
    if too_far.size:
        j = too_far[0]
        raise ModelError(
            f"{too_far.size} point(s) lie outside the mesh, first: point {j} at "
            f"{points[j].tolist()} is {distance[j]:.3g} from the nearest element "
            f"(tolerance {tolerance:.3g})"
        )
    return element, bary


def _search(
    mesh: TetMesh, tree: cKDTree, reach: float, x: np.ndarray, nearest: np.ndarray
) -> tuple[int, np.ndarray]:
    """:func:`_best_element` over all elements, searched among those it can choose: an element
    holding x has its centroid within `reach` (the largest centroid-to-node distance) of x,
    and an element whose clamped point is within d of x has its centroid within d + reach. So
    the elements within `reach`, then (none holding x) those within the best distance found
    so far plus `reach`, in index order (ties resolved as over all elements)."""
    reach = reach * (1.0 + 1e-9)  # round-off at the bound's edge
    near = np.union1d(tree.query_ball_point(x, reach), nearest).astype(np.int64)
    element, bary = _best_element(mesh, near, x)
    if bary.min() >= -_INSIDE_EPS:
        return element, bary
    found = np.einsum("i,ij->j", _clamped(bary), mesh.points[mesh.tets[element]])
    distance = float(np.linalg.norm(found - x))
    wider = np.asarray(tree.query_ball_point(x, distance + reach), dtype=np.int64)
    return _best_element(mesh, np.sort(wider), x)


def _best_element(mesh: TetMesh, candidates: np.ndarray, x: np.ndarray) -> tuple[int, np.ndarray]:
    """Among `candidates`, the element containing x, or else the one nearest to x."""
    bary = barycentric_coordinates(mesh, candidates, np.broadcast_to(x, (candidates.size, 3)))
    inside = np.flatnonzero(bary.min(axis=1) >= -_INSIDE_EPS)
    if inside.size:
        best = inside[np.argmax(bary[inside].min(axis=1))]
        return int(candidates[best]), bary[best]
    # The clamped barycentric point lies in the element: its distance bounds the true one.
    nodes = mesh.points[mesh.tets[candidates]]
    projected = np.einsum("ci,cij->cj", _clamped(bary), nodes)
    best = int(np.argmin(np.linalg.norm(projected - x, axis=1)))
    return int(candidates[best]), bary[best]
