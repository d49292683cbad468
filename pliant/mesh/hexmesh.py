"""Hexahedral meshes: regular grids and sparse grids voxelising a closed surface (SOFA's
RegularGridTopology and SparseGridTopology).

Hexahedra list their eight nodes in VTK's (and SOFA's) order: the bottom face (z-) counter-
clockwise seen from above, (0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), then the top face
(z+) in the same order. Natural coordinates xi of node a are :data:`CORNERS` [a] in
{-1, 1}^3 and its trilinear shape function N_a = prod_i (1 + xi_a,i xi_i) / 8.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit
from scipy import ndimage
from scipy.spatial import cKDTree

from pliant.errors import MeshError, ModelError
from pliant.mesh.locate import locate_points
from pliant.mesh.tetmesh import TetMesh

CORNERS = np.array(
    [
        [-1, -1, -1],
        [1, -1, -1],
        [1, 1, -1],
        [-1, 1, -1],
        [-1, -1, 1],
        [1, -1, 1],
        [1, 1, 1],
        [-1, 1, 1],
    ],
    dtype=float,
)
# The six faces of a hexahedron, outward by the right-hand rule.
_FACES = np.array(
    [[0, 3, 2, 1], [4, 5, 6, 7], [0, 1, 5, 4], [2, 3, 7, 6], [1, 2, 6, 5], [0, 4, 7, 3]]
)
# Six tetrahedra around the diagonal 0-6 fill a hexahedron (to locate points in it).
_SPLIT = np.array(
    [[0, 1, 2, 6], [0, 2, 3, 6], [0, 3, 7, 6], [0, 7, 4, 6], [0, 4, 5, 6], [0, 5, 1, 6]]
)


def shape_functions(xi: np.ndarray) -> np.ndarray:
    """Trilinear shape functions (k, 8) at natural coordinates xi (k, 3)."""
    return np.prod(1.0 + xi[:, None, :] * CORNERS[None], axis=2) / 8.0


def shape_derivatives(xi: np.ndarray) -> np.ndarray:
    """dN_a / dxi_j, (k, 8, 3), at natural coordinates xi (k, 3)."""
    factors = 1.0 + xi[:, None, :] * CORNERS[None]  # (k, 8, 3)
    out = np.empty(factors.shape)
    for j in range(3):
        others = [i for i in range(3) if i != j]
        out[:, :, j] = CORNERS[None, :, j] * factors[:, :, others[0]] * factors[:, :, others[1]]
    return out / 8.0


@dataclass(frozen=True)
class HexMesh:
    """A mesh of trilinear hexahedra.

    Attributes:
        points: (n, 3) node coordinates.
        hexes: (m, 8) node indices, VTK order (see the module).
    """

    points: np.ndarray
    hexes: np.ndarray

    def __post_init__(self) -> None:
        points = np.ascontiguousarray(self.points, dtype=np.float64)
        hexes = np.ascontiguousarray(self.hexes, dtype=np.int64)
        if points.ndim != 2 or points.shape[1] != 3 or not np.isfinite(points).all():
            raise MeshError(f"points must be a finite (n, 3) array, got shape {points.shape}")
        if hexes.ndim != 2 or hexes.shape[1] != 8 or hexes.shape[0] == 0:
            raise MeshError(f"hexes must be a non-empty (m, 8) array, got shape {hexes.shape}")
        if hexes.min() < 0 or hexes.max() >= points.shape[0]:
            raise MeshError(f"hexes index nodes outside [0, {points.shape[0]})")
        unused = points.shape[0] - np.unique(hexes).size
        if unused:
            raise MeshError(f"{unused} nodes belong to no hexahedron")
        object.__setattr__(self, "points", points)
        object.__setattr__(self, "hexes", hexes)
        # Natural-coordinate Jacobians at the centres: an inverted or flat cell is refused.
        centre = np.einsum("mai,aj->mij", points[hexes], shape_derivatives(np.zeros((1, 3)))[0])
        bad = np.flatnonzero(~(np.linalg.det(centre) > 0.0))
        if bad.size:
            raise MeshError(
                f"{bad.size} hexahedra are inverted or flat (first: {int(bad[0])}); nodes go"
                " in VTK order, bottom face counter-clockwise seen from above, then the top"
            )

    @property
    def n_nodes(self) -> int:
        return int(self.points.shape[0])

    @property
    def n_hexes(self) -> int:
        return int(self.hexes.shape[0])

    def boundary_quads(self) -> np.ndarray:
        """Boundary faces (k, 4), outward."""
        faces = self.hexes[:, _FACES].reshape(-1, 4)
        _, inverse, counts = np.unique(
            np.sort(faces, axis=1), axis=0, return_inverse=True, return_counts=True
        )
        return faces[counts[inverse.ravel()] == 1]

    def boundary_triangles(self) -> np.ndarray:
        """Boundary faces split in two triangles each (k, 3), outward."""
        quads = self.boundary_quads()
        return np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])

    def tetrahedra(self) -> TetMesh:
        """Six tetrahedra per hexahedron (element e's are 6 e ... 6 e + 5), to locate points."""
        return TetMesh(self.points, self.hexes[:, _SPLIT].reshape(-1, 4))

    def natural_coordinates(self, cells: np.ndarray, points: np.ndarray) -> np.ndarray:
        """Natural coordinates (k, 3) of points[j] in hexahedron cells[j] (Newton on the
        trilinear map; one step for a box)."""
        nodes = self.points[self.hexes[cells]]  # (k, 8, 3)
        xi = np.zeros((points.shape[0], 3))
        for _ in range(20):
            residual = np.einsum("ka,kai->ki", shape_functions(xi), nodes) - points
            jac = np.einsum("kai,kaj->kij", nodes, shape_derivatives(xi))
            step = np.linalg.solve(jac, residual[..., None])[..., 0]
            xi -= step
            if np.abs(step).max(initial=0.0) < 1e-13:
                break
        return xi

    def embed(
        self, points: np.ndarray, *, tolerance: float, outside: str = "project"
    ) -> tuple[np.ndarray, np.ndarray]:
        """(k, 8) nodes and trilinear weights of points carried by the mesh (SOFA's
        BarycentricMapping on a grid): in the cell containing each; a point outside (up to
        `tolerance`) in its nearest cell, its coordinates clamped onto the cell ("project") or
        extrapolated ("keep", SOFA's)."""
        # The six tetrahedra of each cell check the distance and give one candidate; the cells
        # with the nearest centres give the others (a cell's curved faces may leave a point in
        # a neighbour's tetrahedra).
        tet, _ = locate_points(self.tetrahedra(), points, tolerance=tolerance, outside=outside)
        centres = self.points[self.hexes].mean(axis=1)
        k = min(8, self.n_hexes)
        _, near = cKDTree(centres).query(points, k=k)
        candidates = np.column_stack([tet // _SPLIT.shape[0], near.reshape(len(points), k)])
        xi = self.natural_coordinates(
            candidates.ravel(), np.repeat(points, candidates.shape[1], axis=0)
        ).reshape(*candidates.shape, 3)
        spread = np.abs(xi).max(axis=2)
        best = np.argmin(spread, axis=1)
        rows = np.arange(len(points))
        cells, coords = candidates[rows, best], xi[rows, best]
        out = spread[rows, best] > 1.0 + 1e-9
        if outside == "project":
            coords = np.clip(coords, -1.0, 1.0)
        elif out.any():  # SOFA: the cell whose centre is nearest, coordinates extrapolated
            cells[out] = candidates[out, 1]
            coords[out] = xi[out, 1]
        return self.hexes[cells], shape_functions(coords)


def regular_grid(n, lower, upper) -> HexMesh:
    """SOFA's RegularGridTopology: n = (nx, ny, nz) nodes along x, y, z (at least 2 each)
    between the corners `lower` and `upper`; node (i, j, k) is i + nx (j + ny k)."""
    n = np.asarray(n, dtype=np.int64).reshape(-1)
    lower, upper = np.asarray(lower, float).reshape(-1), np.asarray(upper, float).reshape(-1)
    if n.size != 3 or np.any(n < 2):
        raise ModelError(f"a grid has at least 2 nodes along each axis, got n = {n.tolist()}")
    if lower.size != 3 or upper.size != 3 or not np.all(upper > lower):
        raise ModelError(f"a grid needs min < max on each axis, got {lower} and {upper}")
    axes = [np.linspace(lower[i], upper[i], n[i]) for i in range(3)]
    z, y, x = np.meshgrid(axes[2], axes[1], axes[0], indexing="ij")
    points = np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)
    return HexMesh(points, _grid_cells(n, np.ones(n - 1, dtype=bool)))


def _grid_cells(n: np.ndarray, keep: np.ndarray) -> np.ndarray:
    """Hexahedra (VTK order, node i + nx (j + ny k)) of the cells keep[i, j, k], cells in
    x-fastest order."""
    k, j, i = np.nonzero(keep.transpose(2, 1, 0))
    base = i + n[0] * (j + n[1] * k)
    dx, dy, dz = 1, n[0], n[0] * n[1]
    offsets = np.array([0, dx, dx + dy, dy, dz, dz + dx, dz + dx + dy, dz + dy])
    return base[:, None] + offsets[None, :]


def sparse_grid(
    vertices: np.ndarray,
    triangles: np.ndarray,
    n,
    lower=None,
    upper=None,
    *,
    cell_width: float = 0.0,
    only_inside: bool = False,
    fill_weighted: bool = True,
    finer_levels: int = 0,
) -> tuple[HexMesh, np.ndarray]:
    """SOFA's SparseGridTopology built from a closed surface, and its cells' stiffness
    coefficients.

    The cells kept are those of the regular grid (n nodes per axis between `lower` and
    `upper`; by default the surface's bounding box grown by 1 % of its size on each side;
    `cell_width` > 0 sets n from it) that the surface crosses (BOUNDARY cells, dropped when
    `only_inside`) or that lie inside it (INSIDE: not reached from the grid's border through
    faces of uncrossed cells). Boundary cells come first, then inside ones, each in grid order
    (x fastest); nodes are sorted by x, then y, then z (SOFA's order). A cell's coefficient is
    0.5 on the boundary with `fill_weighted` (SOFA's default), else 1.

    With `finer_levels` L > 0 (SOFA's ``nbVirtualFinerLevels``) the surface is voxelised on
    the grid 2^L times finer, and each coarse cell, made of 8 finer ones, is kept when one of
    them is, INSIDE when all are, with the mean of their coefficients (0 for dropped ones).
    """
    vertices = np.asarray(vertices, dtype=float)
    triangles = np.asarray(triangles, dtype=np.int64)
    if vertices.ndim != 2 or vertices.shape[1] != 3 or triangles.ndim != 2 or not triangles.size:
        raise ModelError("a sparse grid needs a surface: (n, 3) vertices and (k, 3) triangles")
    if lower is None or upper is None or (not np.any(lower) and not np.any(upper)):
        lo, hi = vertices.min(axis=0), vertices.max(axis=0)
        lower, upper = lo - (hi - lo) / 100.0, hi + (hi - lo) / 100.0
    lower, upper = np.asarray(lower, float).reshape(-1), np.asarray(upper, float).reshape(-1)
    n = np.asarray(n, dtype=np.int64).reshape(-1)
    if n.size != 3 or lower.size != 3 or upper.size != 3 or not np.all(upper > lower):
        raise ModelError(f"a sparse grid needs n (3 values) and min < max, got {n}, {lower}")
    if cell_width > 0.0:
        n = np.ceil((upper - lower) / cell_width).astype(np.int64) + 1
    n = np.maximum(n, 2)  # SOFA raises n below 2 to 2
    fine = (n - 1) * 2**finer_levels
    crossed = _crossed_cells(vertices, triangles, lower, (upper - lower) / fine, fine)
    # Cells not crossed and connected (by faces) to the grid's border are outside.
    labels, _ = ndimage.label(~crossed)
    border = np.zeros(crossed.shape, dtype=bool)
    border[[0, -1], :, :] = border[:, [0, -1], :] = border[:, :, [0, -1]] = True
    outside = np.isin(labels, np.unique(labels[border & ~crossed]))
    inside = ~crossed & ~outside
    if only_inside:
        crossed = np.zeros_like(crossed)
    full = regular_grid(n, lower, upper)
    if finer_levels == 0:
        cells = np.concatenate([_grid_cells(n, crossed), _grid_cells(n, inside)])
        coefs = np.where(
            np.arange(cells.shape[0]) < crossed.sum(), 0.5 if fill_weighted else 1.0, 1.0
        )
    else:
        coef = np.where(crossed, 0.5 if fill_weighted else 1.0, np.where(inside, 1.0, 0.0))
        kept = crossed | inside
        for _ in range(finer_levels):
            shape = tuple(s // 2 for s in coef.shape)
            blocks = (shape[0], 2, shape[1], 2, shape[2], 2)
            coef = coef.reshape(blocks).sum(axis=(1, 3, 5)) / 8.0
            kept = kept.reshape(blocks).any(axis=(1, 3, 5))
        # SOFA's coarse cells come x slowest, z fastest.
        i, j, k = np.nonzero(kept)
        base = i + n[0] * (j + n[1] * k)
        cells = base[:, None] + _grid_cells(n, np.ones((1, 1, 1), dtype=bool))[0][None, :]
        coefs = coef[i, j, k]
    if cells.shape[0] == 0:
        raise ModelError("the sparse grid holds no cell: is the surface closed and inside it?")
    used = np.unique(cells)
    order = np.lexsort(full.points[used].T[::-1])  # x, then y, then z
    renumber = np.empty(full.n_nodes, dtype=np.int64)
    renumber[used[order]] = np.arange(used.size)
    return HexMesh(full.points[used[order]], renumber[cells]), coefs


def _crossed_cells(vertices, triangles, lower, step, cells) -> np.ndarray:
    """(nx, ny, nz) cells that a triangle of the surface intersects."""
    out = np.zeros(tuple(int(c) for c in cells), dtype=bool)
    _mark_crossed(vertices, triangles, lower, step, out)
    return out


@njit(cache=True)
def _mark_crossed(vertices, triangles, lower, step, out):
    half = 0.5 * step
    for t in range(triangles.shape[0]):
        a = vertices[triangles[t, 0]]
        b = vertices[triangles[t, 1]]
        c = vertices[triangles[t, 2]]
        lo = np.empty(3, np.int64)
        hi = np.empty(3, np.int64)
        for i in range(3):
            m0 = min(a[i], b[i], c[i])
            m1 = max(a[i], b[i], c[i])
            lo[i] = max(0, int(np.floor((m0 - lower[i]) / step[i])))
            hi[i] = min(out.shape[i] - 1, int(np.floor((m1 - lower[i]) / step[i])))
        for i in range(lo[0], hi[0] + 1):
            for j in range(lo[1], hi[1] + 1):
                for k in range(lo[2], hi[2] + 1):
                    if out[i, j, k]:
                        continue
                    centre = lower + (np.array([i, j, k]) + 0.5) * step
                    if _triangle_meets_box(a - centre, b - centre, c - centre, half):
                        out[i, j, k] = True


@njit(cache=True)
def _triangle_meets_box(v0, v1, v2, h):
    """Separating-axis test of a triangle (vertices relative to the box centre) against the
    box of half sizes h (Akenine-Moller): the 3 box axes, the triangle's normal and the 9
    cross products of edges and axes; touching counts as meeting."""
    for i in range(3):
        if min(v0[i], v1[i], v2[i]) > h[i] or max(v0[i], v1[i], v2[i]) < -h[i]:
            return False
    e0, e1, e2 = v1 - v0, v2 - v1, v0 - v2
    normal = np.cross(e0, e1)
    r = h[0] * abs(normal[0]) + h[1] * abs(normal[1]) + h[2] * abs(normal[2])
    if abs(np.dot(normal, v0)) > r:
        return False
    for edge in (e0, e1, e2):
        for i in range(3):
            axis = np.zeros(3)
            axis[i] = 1.0
            a = np.cross(axis, edge)
            p0, p1, p2 = np.dot(a, v0), np.dot(a, v1), np.dot(a, v2)
            r = h[0] * abs(a[0]) + h[1] * abs(a[1]) + h[2] * abs(a[2])
            if min(p0, p1, p2) > r or max(p0, p1, p2) < -r:
                return False
    return True
