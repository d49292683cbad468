"""Deformable body of corotational trilinear hexahedra: SOFA's HexahedronFEMForceField.

Each hexahedron (eight nodes, trilinear shape functions, 2 x 2 x 2 Gauss points) has the
linear elastic stiffness K0 of its rest shape; its rotation R follows the element's averaged
edges (:mod:`pliant.fem.hex_kernels`), and its force is f = -R K0 (R^T x - X): SOFA's
corotational hexahedron, with ``Corotational(rotation="large")`` (SOFA's default method) or
``rotation="polar"``. SOFA integrates K0 in closed form for the box its element is in its own
frame; 2 x 2 x 2 Gauss points integrate the same polynomials exactly, and stay right for
hexahedra that are no boxes. The tangent is SOFA's, R K0 R^T (also when the exact one is
asked for: the rotation's variation is left out, as for the "large" tetrahedron).

The body answers the solvers as :class:`pliant.fem.body.TetBody` does (it is one, with
hexahedra for elements), so the implicit and static solvers, cables, effectors, held nodes
and loads work on it unchanged.
"""

from __future__ import annotations

from functools import cached_property
from typing import Any

import numpy as np

from pliant.errors import MaterialError, ModelError
from pliant.fem import hex_kernels, kernels
from pliant.fem.body import (
    BodyOptions,
    Linearisation,
    TetBody,
    _sized_threads,
)
from pliant.fem.material import (
    COROTATIONAL,
    COROTATIONAL_LARGE,
    COROTATIONAL_LARGE_INVERTIBLE,
    Corotational,
)
from pliant.mesh.hexmesh import CORNERS, HexMesh, shape_derivatives, shape_functions

# The 2 x 2 x 2 Gauss points (weights 1) in natural coordinates.
_GAUSS = CORNERS / np.sqrt(3.0)


def rest_stiffness(
    points: np.ndarray, hexes: np.ndarray, mu: np.ndarray, lam: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Linear elastic stiffness (m, 24, 24) of trilinear hexahedra at rest (2 x 2 x 2 Gauss
    points), with their volumes (m,) and Gauss weights det J (m, 8)."""
    dn = shape_derivatives(_GAUSS)  # (q, a, j)
    jac = np.einsum("mai,qaj->mqij", points[hexes], dn)
    weights = np.linalg.det(jac)
    grads = np.einsum("qaj,mqji->mqai", dn, np.linalg.inv(jac))  # dN_a / dX_i
    dot = np.einsum("mqai,mqbi->mqab", grads, grads)
    eye = np.eye(3)
    k = np.einsum("mq,mqab,ij->maibj", weights, dot, eye) * mu[:, None, None, None, None]
    k += mu[:, None, None, None, None] * np.einsum("mq,mqbi,mqaj->maibj", weights, grads, grads)
    k += lam[:, None, None, None, None] * np.einsum("mq,mqai,mqbj->maibj", weights, grads, grads)
    return k.reshape(-1, 24, 24), weights.sum(axis=1), weights


class HexBody(TetBody):
    """A deformable body of corotational trilinear hexahedra.

    Args:
        mesh: the hexahedral mesh (:func:`pliant.mesh.hexmesh.regular_grid`,
            :func:`~pliant.mesh.hexmesh.sparse_grid`).
        material: ``Corotational(E, nu, rotation)``, "large" (SOFA's default) or "polar".
        stiffness_weights: (m,) factors of each element's stiffness (SOFA's sparse grids with
            ``fillWeighted`` weigh the cells the surface crosses by 0.5); default 1.
        mass: "lumped" (the row sums of the element mass matrices on the nodes, SOFA's
            MeshMatrixMass with lumping), "uniform" (total mass / nodes, SOFA's UniformMass),
            "consistent" or "none" (a massless body, as :class:`pliant.fem.body.TetBody`'s).

    The other keywords are those of :class:`pliant.fem.body.BodyOptions`, as for
    :class:`pliant.fem.body.TetBody` (a hexahedral body has no membranes or frame nodes).
    """

    def __init__(
        self,
        mesh: HexMesh,
        material: Corotational,
        *,
        stiffness_weights: np.ndarray | None = None,
        **options: Any,
    ) -> None:
        tags = (COROTATIONAL, COROTATIONAL_LARGE, COROTATIONAL_LARGE_INVERTIBLE)
        if not isinstance(material, Corotational) or material.kernel_tag not in tags:
            raise MaterialError(
                f"hexahedra are corotational (SOFA's HexahedronFEMForceField), got {material!r}"
            )
        self.mesh = mesh
        self.material = material
        self.rest_positions = mesh.points
        self.hexes = mesh.hexes
        m = self.hexes.shape[0]
        weights = np.ones(m) if stiffness_weights is None else np.asarray(stiffness_weights)
        if weights.shape != (m,) or not np.all(np.isfinite(weights)) or np.any(weights <= 0):
            raise ModelError(f"stiffness_weights must be {m} finite positive factors")
        self.mu = np.full(m, material.mu)
        self.lam = np.full(m, material.lam)
        k0, self.volumes, self._gauss_weights = rest_stiffness(
            self.rest_positions, self.hexes, self.mu, self.lam
        )
        self.k0 = np.ascontiguousarray(k0 * weights[:, None, None])
        self.rest_frames, self._rest_dets = hex_kernels.rest_frames(
            self.rest_positions, self.hexes, CORNERS, material.kernel_tag
        )
        self._hold_and_weigh(self.hexes, BodyOptions(**options), ())

    # --- layout -----------------------------------------------------------------------------
    @property
    def element_nodes(self) -> np.ndarray:
        return self.hexes

    @property
    def label(self) -> str:
        return f"{self.hexes.shape[0]} hexahedra"

    @cached_property
    def boundary_triangles(self) -> np.ndarray:
        return self.mesh.boundary_triangles()

    def vtk_cells(self) -> tuple[str, np.ndarray, np.ndarray]:
        return "hexahedron", self.hexes, np.arange(self.n_nodes)

    # --- mass -------------------------------------------------------------------------------
    def _element_masses(self) -> np.ndarray:
        """Element mass matrices rho int N_a N_b (m, 8, 8) (2 x 2 x 2 Gauss points: exact)."""
        n = shape_functions(_GAUSS)  # (q, a)
        return self.density * np.einsum("mq,qa,qb->mab", self._gauss_weights, n, n)

    def _node_masses(self, mass: str) -> np.ndarray:
        if mass == "uniform":
            return np.full(self.n_nodes, self.total_mass / self.n_nodes)
        if mass in ("lumped", "consistent"):
            out = np.zeros(self.n_nodes)
            np.add.at(out, self.hexes.ravel(), self._element_masses().sum(axis=2).ravel())
            return out
        raise ModelError(f"mass must be 'lumped', 'uniform', 'consistent' or 'none', got {mass!r}")

    def _mass_data(self, mass: str) -> np.ndarray:
        if mass != "consistent":
            return super()._mass_data(mass)
        blocks = np.einsum("mab,ij->maibj", self._element_masses(), np.eye(3)).reshape(-1, 24, 24)
        data = np.zeros(self.pattern.nnz)
        kernels.scatter_add(np.ascontiguousarray(blocks), 1.0, self.pattern.scatter, data)
        return data

    # --- elasticity -------------------------------------------------------------------------
    def _element_forces(self, x: np.ndarray, v: np.ndarray) -> tuple:
        """Per-element forces (and K_s v when `v` has rows) side by side, (m, 8, 3 or 6), the
        energy, the element rotations and their determinants at `x`."""
        m = self.n_elements
        with_v = v.shape[0] > 0
        elem = np.empty((m, 8, 6 if with_v else 3))
        frames = np.empty((m, 3, 3))
        dets = np.empty(m)
        energy = hex_kernels.internal_forces(
            x,
            v,
            self.hexes,
            self.rest_positions,
            self.k0,
            CORNERS,
            self.material.kernel_tag,
            self.rest_frames,
            self._rest_dets,
            elem[:, :, :3],
            elem[:, :, 3:] if with_v else np.empty((0, 8, 3)),
            frames,
            dets,
        )
        return elem, energy, frames, dets

    @_sized_threads
    def stiffness_matvec(
        self, lin: Linearisation, u: np.ndarray, *, exact: bool = False
    ) -> np.ndarray:
        """K_s u on the free DoFs (SOFA's R K0 R^T); u is (n_free,) or (n_free, k)."""
        cols = np.ascontiguousarray(u[:, None] if u.ndim == 1 else u, dtype=np.float64)
        elem_out = np.empty((self.n_elements, 8, 3, cols.shape[1]))
        hex_kernels.stiffness_matvec(
            cols, self._elem_dofs, self.k0, lin.frames, lin.dets, self.material.kernel_tag, elem_out
        )
        out = np.empty_like(cols)
        kernels.gather_free(elem_out, self._incidence_ptr, self._incidence, self.free_index, out)
        self._add_surface_matvec(lin, cols, out)
        return out[:, 0] if u.ndim == 1 else out

    def stiffness_data(self, lin: Linearisation, *, exact: bool = False) -> np.ndarray:
        """Tangent stiffness on the free DoFs, as data aligned with `self.pattern`."""
        data = np.zeros(self.pattern.nnz)
        hex_kernels.assembly(
            self.k0, lin.frames, lin.dets, self.material.kernel_tag, self.pattern.scatter, data
        )
        self._add_surface_data(lin, data)
        return data
