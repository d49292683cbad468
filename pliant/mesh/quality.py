"""Checks that a tetrahedral mesh can be simulated, and the repairs that loading a file needs.

A mesh is usable when its arrays are well formed, every element has a clearly positive volume
and a shape that is not flat, every node belongs to an element, and the elements form one
connected body.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from pliant.errors import (
    DegenerateElementError,
    DisconnectedMeshError,
    InvertedElementError,
    MeshError,
)

# |V| below this fraction of the bounding-box diagonal cubed is numerical zero.
RELATIVE_VOLUME_TOLERANCE = 1e-12
# Shape quality below which an element is flat for any practical purpose. The reference SOFA
# meshes bottom out around 3e-3, gmsh output around 1e-2.
MIN_SHAPE_QUALITY = 1e-4
# Nodes closer than this fraction of the bounding-box diagonal are one place (a crack).
COINCIDENT_TOLERANCE = 1e-10

# Node pairs of the six edges of a tetrahedron.
_EDGES = np.array([[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]])


def signed_volumes(points: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """Signed volume of each tetrahedron, ((p1 - p0) x (p2 - p0)) . (p3 - p0) / 6, shape (m,)."""
    p = points[tets]
    e1, e2, e3 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0], p[:, 3] - p[:, 0]
    return np.einsum("ij,ij->i", np.cross(e1, e2), e3) / 6.0


def shape_quality(points: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """Volume-to-edge shape quality of each tetrahedron, shape (m,).

    q = 6 sqrt(2) |V| / l_rms^3 with l_rms the root mean square edge length: 1 for the regular
    tetrahedron, 0 for a flat one (Parthasarathy, Graichen & Hathaway 1994, "A comparison of
    tetrahedron quality measures").
    """
    p = points[tets]
    edges = p[:, _EDGES[:, 1]] - p[:, _EDGES[:, 0]]
    l_rms = np.sqrt(np.einsum("ijk,ijk->i", edges, edges) / 6.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        q = 6.0 * np.sqrt(2.0) * np.abs(signed_volumes(points, tets)) / l_rms**3
    return np.nan_to_num(q, nan=0.0)


def _check_arrays(points: np.ndarray, tets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    points = np.asarray(points)
    tets = np.asarray(tets)
    if points.ndim != 2 or points.shape[1] != 3 or points.shape[0] == 0:
        raise MeshError(f"points must be a non-empty (n, 3) array, got shape {points.shape}")
    if tets.ndim != 2 or tets.shape[1] != 4 or tets.shape[0] == 0:
        raise MeshError(f"tets must be a non-empty (m, 4) array, got shape {tets.shape}")
    if not np.issubdtype(points.dtype, np.floating) and not np.issubdtype(points.dtype, np.integer):
        raise MeshError(f"points must be numeric, got dtype {points.dtype}")
    if not np.issubdtype(tets.dtype, np.integer):
        raise MeshError(f"tets must hold integer node indices, got dtype {tets.dtype}")
    bad_rows = np.flatnonzero(~np.isfinite(points).all(axis=1))
    if bad_rows.size:
        raise MeshError(
            f"{bad_rows.size} node(s) have non-finite coordinates, first: node {bad_rows[0]} "
            f"at {points[bad_rows[0]].tolist()}"
        )
    n = points.shape[0]
    out_of_range = np.flatnonzero(((tets < 0) | (tets >= n)).any(axis=1))
    if out_of_range.size:
        e = out_of_range[0]
        raise MeshError(
            f"{out_of_range.size} element(s) reference nodes outside [0, {n}), "
            f"first: element {e} with nodes {tets[e].tolist()}"
        )
    s = np.sort(tets, axis=1)
    repeated = np.flatnonzero((s[:, 1:] == s[:, :-1]).any(axis=1))
    if repeated.size:
        e = repeated[0]
        raise MeshError(
            f"{repeated.size} element(s) repeat a node, first: element {e} with nodes "
            f"{tets[e].tolist()}"
        )
    return points.astype(np.float64, copy=False), tets.astype(np.int64, copy=False)


def component_labels(n_nodes: int, tets: np.ndarray) -> tuple[int, np.ndarray]:
    """Connected components of the node graph in which a tetrahedron joins its four nodes.

    Returns the number of components and the label of each node.
    """
    rows = tets[:, _EDGES[:, 0]].ravel()
    cols = tets[:, _EDGES[:, 1]].ravel()
    graph = sp.coo_matrix((np.ones(rows.size, dtype=np.int8), (rows, cols)), (n_nodes, n_nodes))
    return connected_components(graph, directed=False)


def validate_mesh(
    points: np.ndarray,
    tets: np.ndarray,
    *,
    allow_disconnected: bool = False,
    min_quality: float = MIN_SHAPE_QUALITY,
) -> None:
    """Raise if the mesh cannot be simulated; return None if it can.

    Args:
        points: (n, 3) node coordinates.
        tets: (m, 4) node indices, positively oriented.
        allow_disconnected: accept several separate bodies in one mesh.
        min_quality: elements whose `shape_quality` is below this are flat.

    Raises:
        MeshError: wrong shapes or dtypes, empty arrays, non-finite coordinates, indices out of
            range, a node repeated within an element, or nodes that belong to no element.
        DegenerateElementError: |volume| below 1e-12 (bounding-box diagonal)^3, or a flat shape.
        InvertedElementError: negative signed volume.
        DisconnectedMeshError: several connected components (unless allowed).
    """
    points, tets = _check_arrays(points, tets)

    unused = np.setdiff1d(np.arange(points.shape[0]), tets)
    if unused.size:
        raise MeshError(
            f"{unused.size} node(s) belong to no element (first: node {unused[0]}); they would "
            "make the stiffness matrix singular, remove them with remove_unused_nodes"
        )

    diagonal = float(np.linalg.norm(points.max(axis=0) - points.min(axis=0)))
    # Two nodes at one place are a crack: the elements on either side share a face
    # geometrically but not its nodes, so the body can open there without any strain.
    cells = np.round(points / max(COINCIDENT_TOLERANCE * diagonal, np.finfo(float).tiny))
    _, first, counts = np.unique(cells, axis=0, return_index=True, return_counts=True)
    if np.any(counts > 1):
        twin = int(first[np.flatnonzero(counts > 1)[0]])
        others = np.flatnonzero(np.all(cells == cells[twin], axis=1))
        raise MeshError(
            f"{int(np.sum(counts[counts > 1]))} nodes coincide with another (first: nodes"
            f" {others.tolist()} at {points[twin].tolist()}): the mesh has a crack there;"
            " merge the coincident nodes"
        )
    volumes = signed_volumes(points, tets)
    quality = shape_quality(points, tets)
    tiny = np.abs(volumes) <= RELATIVE_VOLUME_TOLERANCE * diagonal**3
    degenerate = np.flatnonzero(tiny | (quality < min_quality))
    if degenerate.size:
        e = degenerate[0]
        raise DegenerateElementError(
            f"{degenerate.size} element(s) are degenerate (near-zero volume or flat shape), "
            f"first: element {e} with volume {volumes[e]:.3g} and shape quality "
            f"{quality[e]:.3g} (minimum {min_quality:g}; bounding-box diagonal {diagonal:.3g})"
        )
    inverted = np.flatnonzero(volumes < 0.0)
    if inverted.size:
        e = inverted[0]
        raise InvertedElementError(
            f"{inverted.size} element(s) have negative signed volume, first: element {e} "
            f"with volume {volumes[e]:.3g}; if the file uses the opposite node ordering, "
            "apply fix_orientation"
        )

    if not allow_disconnected:
        n_components, labels = component_labels(points.shape[0], tets)
        if n_components > 1:
            sizes = np.bincount(labels[tets[:, 0]], minlength=n_components)
            raise DisconnectedMeshError(
                f"the mesh has {n_components} separate components of "
                f"{sorted(sizes.tolist(), reverse=True)} elements; pass "
                "allow_disconnected=True if the bodies are meant to be separate"
            )


def fix_orientation(points: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """Return a copy of `tets` in which negatively oriented elements have two nodes swapped."""
    tets = np.array(tets, dtype=np.int64, copy=True)
    flip = signed_volumes(np.asarray(points, dtype=np.float64), tets) < 0.0
    tets[flip] = tets[flip][:, [0, 2, 1, 3]]
    return tets


def remove_unused_nodes(points: np.ndarray, tets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Drop nodes that no element uses and renumber the elements, keeping the node order."""
    points = np.asarray(points, dtype=np.float64)
    tets = np.asarray(tets, dtype=np.int64)
    if tets.size and (tets.min() < 0 or tets.max() >= points.shape[0]):
        raise MeshError(
            f"element node indices span [{tets.min()}, {tets.max()}], outside the "
            f"{points.shape[0]} nodes"
        )
    used = np.unique(tets)
    new_index = np.full(points.shape[0], -1, dtype=np.int64)
    new_index[used] = np.arange(used.size)
    return points[used].copy(), new_index[tets]
