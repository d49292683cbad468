"""Hexahedral bodies of SOFA scenes: a HexahedronFEMForceField on a RegularGridTopology or a
SparseGridTopology.

* ``RegularGridTopology``: ``n`` (or ``nx ny nz``) nodes per axis between ``min`` and ``max``
  (or ``xmin`` ... ``zmax``); node (i, j, k) is i + nx (j + ny k), as in SOFA.
* ``SparseGridTopology``: the cells of such a grid that a closed surface (its ``fileTopology``
  or ``filename``, or the loader its ``src`` or ``position`` links to) crosses or encloses;
  ``min``/``max`` default to the surface's bounding box grown by 1 % a side, ``cellWidth``
  sets ``n``, ``onlyInsideCells`` drops the crossed cells, ``fillWeighted`` (SOFA's default)
  halves their stiffness and ``nbVirtualFinerLevels`` averages the stiffness of finer cells
  (:func:`pliant.mesh.hexmesh.sparse_grid`).
* ``HexahedronFEMForceField``: ``youngModulus``, ``poissonRatio``, ``method`` "large" (SOFA's
  default) or "polar" (:class:`pliant.fem.hexbody.HexBody`). SOFA's "small" (linear, no
  rotation) has no Pliant element.

A TetrahedronFEMForceField on a grid cuts each cell into six tetrahedra, as SOFA does
(:func:`grid_tetrahedra`). The mass (UniformMass or MeshMatrixMass), held nodes, loads and the
solver are read as for a tetrahedral body; points under the body (cables, effectors, cavities,
collision points) are carried by the trilinear shape functions of the cell they lie in (SOFA's
BarycentricMapping on a grid).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from pliant.errors import ModelError
from pliant.fem.hexbody import HexBody
from pliant.fem.material import Corotational
from pliant.mesh.hexmesh import HexMesh, regular_grid, sparse_grid
from pliant.sofa.bodies import check_held_if_massless
from pliant.sofa.tree import SceneError, SceneNode, SceneObject, data_value, field_numbers

if TYPE_CHECKING:
    from pliant.sofa.loader import _Builder

HEXAHEDRA = "HexahedronFEMForceField"
GRIDS = frozenset({"RegularGridTopology", "SparseGridTopology"})
_METHODS = ("large", "polar")


_numbers = field_numbers


def _triple(obj: SceneObject, key: str, axes: tuple[str, str, str], default) -> np.ndarray:
    """A 3-vector field given whole (``n="4 4 20"``) or per axis (``nx="4" ...``)."""
    if key in obj.attrs or not any(a in obj.attrs for a in axes):
        values = _numbers(obj, key, default)
    else:
        values = np.array([_numbers(obj, a, d)[0] for a, d in zip(axes, default, strict=True)])
    if values.size != 3:
        raise SceneError(f"{obj.path}.{key}: three values expected, got {values.size}")
    return values


def grid_topology(builder: _Builder, node: SceneNode) -> SceneObject:
    """The grid the body's node (or its nearest ancestor) holds."""
    at: SceneNode | None = node
    while at is not None:
        grid = builder._one(at, GRIDS, "grid topologies")
        if grid is not None:
            return grid
        at = at.parent
    raise SceneError(
        f"{node.path}: a HexahedronFEMForceField needs a RegularGridTopology or a"
        " SparseGridTopology (hexahedra from a mesh file are not read)"
    )


def grid_mesh(builder: _Builder, grid: SceneObject) -> tuple[HexMesh, np.ndarray]:
    """The grid's hexahedra and their stiffness coefficients."""
    n = _triple(grid, "n", ("nx", "ny", "nz"), (2, 2, 2)).astype(np.int64)
    lower = _triple(grid, "min", ("xmin", "ymin", "zmin"), (0.0, 0.0, 0.0))
    upper = _triple(grid, "max", ("xmax", "ymax", "zmax"), (0.0, 0.0, 0.0))
    try:
        if grid.type == "RegularGridTopology":
            mesh = regular_grid(n, lower, upper)
            return mesh, np.ones(mesh.n_hexes)
        vertices, triangles = _surface(builder, grid)
        width = _numbers(grid, "cellWidth", [0.0])
        levels = _numbers(grid, "nbVirtualFinerLevels", [0])
        return sparse_grid(
            vertices,
            triangles,
            n,
            None if not (lower.any() or upper.any()) else lower,
            None if not (lower.any() or upper.any()) else upper,
            cell_width=float(width[0]) if width.size else 0.0,
            only_inside=_truth(grid.attrs.get("onlyInsideCells", False)),
            fill_weighted=_truth(grid.attrs.get("fillWeighted", True)),
            finer_levels=int(levels[0]) if levels.size else 0,
        )
    except ModelError as exc:
        raise SceneError(f"{grid.path}: {exc}") from exc


def _truth(value) -> bool:
    """A flag as SOFA reads it: "1", "true" (any case) or a true number."""
    value = data_value(value)
    return value.strip().lower() in ("1", "true") if isinstance(value, str) else bool(value)


def _surface(builder: _Builder, grid: SceneObject) -> tuple[np.ndarray, np.ndarray]:
    """The closed surface a sparse grid voxelises: its file, or the loader it links to."""
    source = None
    for key in ("src", "position"):
        link = grid.attrs.get(key)
        if isinstance(link, str) and link.strip().startswith("@"):
            source = builder.link(grid.node, link)
            break
    name = grid.attrs.get("fileTopology", grid.attrs.get("filename"))
    if source is None and name:
        source = SceneObject("MeshSTLLoader", {"name": grid.name, "filename": name}, grid.node)
    if source is None or "filename" not in source.attrs:
        raise SceneError(f"{grid.path}: no surface to voxelise (fileTopology, or src='@loader')")
    points, cells = builder._loaded(source)
    faces = [cells[k] for k in ("triangle", "quad") if k in cells]
    if not faces:
        raise SceneError(f"{grid.path}: {source.attrs['filename']} holds no triangles")
    triangles = [f if f.shape[1] == 3 else f[:, [0, 1, 2, 0, 2, 3]].reshape(-1, 3) for f in faces]
    return points, np.concatenate(triangles)


# SOFA's TetrahedronFEMForceField on hexahedra: six tetrahedra per cell, the cell's corners
# first mirrored along x (even cells), y (odd rows) and z (odd layers) so that neighbours share
# their faces' diagonals.
_SIX = np.array(
    [[0, 5, 1, 6], [0, 1, 3, 6], [1, 3, 6, 2], [6, 3, 0, 7], [6, 7, 0, 5], [7, 5, 4, 0]]
)
_MIRRORS = np.array([[1, 0, 3, 2, 5, 4, 7, 6], [3, 2, 1, 0, 7, 6, 5, 4], [4, 5, 6, 7, 0, 1, 2, 3]])


def grid_tetrahedra(builder: _Builder, node: SceneNode) -> tuple[np.ndarray, np.ndarray] | None:
    """The points and tetrahedra of a grid on the body's node (None without one), in SOFA's
    order: each cell i in turn, its corners mirrored along x when (i mod nx) is even, along y
    when (i // nx mod ny) is odd, along z when (i // (nx ny)) is odd (nx, ny the cells per
    row and column of a regular grid; 2 and 1 for a sparse grid, as SOFA takes them)."""
    grid = builder._one(node, GRIDS, "grid topologies")
    if grid is None:
        return None
    mesh, _ = grid_mesh(builder, grid)
    nx, ny = 2, 1
    if grid.type == "RegularGridTopology":
        nx, ny = (_triple(grid, "n", ("nx", "ny", "nz"), (2, 2, 2)).astype(np.int64) - 1)[:2]
    cells = mesh.hexes.copy()
    index = np.arange(len(cells))
    for flip, axis in zip(
        [index % nx % 2 == 0, (index // nx) % ny % 2 == 1, (index // (nx * ny)) % 2 == 1],
        _MIRRORS,
        strict=True,
    ):
        cells[flip] = cells[flip][:, axis]
    return mesh.points, cells[:, _SIX].reshape(-1, 4)


def hex_body(
    builder: _Builder, node: SceneNode, fem: SceneObject, gravity: np.ndarray
) -> tuple[HexBody, HexMesh, str]:
    """The body of a HexahedronFEMForceField node: its grid, material, mass, held nodes,
    loads and solver."""
    method = str(fem.attrs.get("method", "large")).lower()
    if method not in _METHODS:
        raise SceneError(
            f"{fem.path}: method {method!r} is not supported for hexahedra ({', '.join(_METHODS)})"
        )
    large = method == "large" and builder.choices.rotation == "scene"
    material = Corotational(
        float(_numbers(fem, "youngModulus", 5000.0)[0]),
        float(_numbers(fem, "poissonRatio", 0.45)[0]),
        "large" if large else "polar",
        inversion=builder.choices.inversion if large else "refuse",
    )
    mesh, weights = grid_mesh(builder, grid_topology(builder, node))
    points = mesh.points
    options, solver_kind = builder.body_options(node, points, gravity)
    body = HexBody(mesh, material, stiffness_weights=weights, **options)
    check_held_if_massless(node, body)
    return body, mesh, solver_kind
