"""Shells of constant-strain triangles: SOFA's TriangleFEMForceField.

Each triangle is a linear elastic membrane in plane stress: the strain (e_xx, e_yy, g_xy) is
constant over it, sigma = D e with D = E / (1 - nu^2) [[1, nu, 0], [nu, 1, 0], [0, 0, (1 -
nu) / 2]], and its stiffness is K0 = A t B^T D B (A its rest area, t the thickness, B the
strain-displacement matrix of its rest shape in its own plane). Bending has no stiffness.

The element's frame is SOFA's: x along its first edge (a -> b), z along the normal of its
first two edges, y = z x x. Under ``method="large"`` (SOFA's default, corotational) the frame R
follows the current triangle, and so does B, as in SOFA's TriangleFEMForceField: the force is
f = -R K u with K = A0 t B^T D B of the current triangle in its frame (A0 the rest area) and
u = R^T (x - x_a) - R0^T (X - X_a) the local displacement (node-major; the z rows of K zero).
A rigid motion strains nothing; the tangent is SOFA's, R K R^T (the variation of the frame and
of B is left out); the energy is 1/2 u^T K u (the force is its gradient to first order in the
strain). Under uniform tension the displacement departs from the uniform stress's by about
2 (sigma / E)^2 L (the first edge turns with the stretch where it is no principal direction).
Under ``method="small"`` the frame and B stay the rest ones: f = -R0 K0 R0^T (x - X), linear
elasticity (forces, energy and tangent exact; it passes the patch test to round-off).

Departure from SOFA: SOFA's "small" element reads the world's x and y components only (a
triangle in a plane z = const) with B of the current triangle; this one is the linear element
in its rest plane.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass
from functools import cached_property
from typing import Any, ClassVar, Literal

import numpy as np

from pliant.errors import MaterialError, ModelError
from pliant.fem import kernels
from pliant.fem.body import BodyOptions, Linearisation, TetBody
from pliant.fem.material import Material

Method = Literal["large", "small"]


@dataclass(frozen=True)
class PlaneStress(Material):
    """The law of a shell of triangles (SOFA's TriangleFEMForceField): Young's modulus,
    Poisson's ratio (0 <= nu < 0.5, as SOFA's data), the thickness t > 0 and the method,
    "large" (corotational) or "small" (linear). It has no compiled kernel (the tetrahedral
    tools that dispatch on one refuse it by name)."""

    thickness: float = 1.0
    method: Method = "large"
    kernel_tag: ClassVar[int] = -1

    def __post_init__(self) -> None:
        super().__post_init__()
        t = self.thickness
        if isinstance(t, bool) or not isinstance(t, numbers.Real) or not math.isfinite(t) or t <= 0:
            raise MaterialError(f"a shell's thickness must be finite and > 0, got {t!r}")
        object.__setattr__(self, "thickness", float(t))
        if self.method not in ("large", "small"):
            raise MaterialError(f"a shell's method is 'large' or 'small', got {self.method!r}")

    def plane_stress_matrix(self) -> np.ndarray:
        """D (3, 3): stress (s_xx, s_yy, s_xy) from strain (e_xx, e_yy, g_xy)."""
        e, nu = self.young_modulus, self.poisson_ratio
        return (
            e
            / (1.0 - nu * nu)
            * np.array([[1.0, nu, 0.0], [nu, 1.0, 0.0], [0.0, 0.0, (1 - nu) / 2]])
        )


def edge_frames(points: np.ndarray, triangles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """SOFA's frames (t, 3, 3) of triangles, columns (x, y, z): x along a -> b, z along
    (b - a) x (c - a); and twice their areas (t,). A degenerate triangle's frame is NaN."""
    a, b, c = (points[triangles[:, k]] for k in range(3))
    e1, e2 = b - a, c - a
    normal = np.cross(e1, e2)
    twice_area = np.linalg.norm(normal, axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        x = e1 / np.linalg.norm(e1, axis=1)[:, None]
        z = normal / twice_area[:, None]
    return np.stack([x, np.cross(z, x), z], axis=-1), twice_area


class TriangleFEM:
    """Constant-strain triangles on nodes (see the module text).

    Args:
        points: (n, 3) rest positions of the nodes.
        triangles: (t, 3) node indices (non-degenerate triangles; the first edge gives the
            element's frame, as in SOFA).
        material: the shell's :class:`PlaneStress` law (E, nu, thickness, method).

    Its :meth:`element_forces` and :meth:`element_stiffness` are those of a
    :class:`pliant.fem.membrane.Membrane` (node-major element vectors and matrices).
    """

    # On a body of tetrahedra (a shell joined beside them), its triangles join nodes that
    # share no tetrahedron: their entries join the body's stiffness pattern.
    spans_elements = True

    def __init__(self, points: np.ndarray, triangles: np.ndarray, material: PlaneStress) -> None:
        if not isinstance(material, PlaneStress):
            raise MaterialError(f"a shell of triangles takes a PlaneStress law, got {material!r}")
        points = np.asarray(points, dtype=float)
        tri = np.ascontiguousarray(triangles, dtype=np.int64)
        if tri.ndim != 2 or tri.shape[1] != 3 or tri.shape[0] == 0:
            raise ModelError(f"triangles must be a non-empty (t, 3) array, got {tri.shape}")
        if tri.min() < 0 or tri.max() >= points.shape[0]:
            raise ModelError(f"triangle node indices must lie in [0, {points.shape[0]})")
        self.triangles = tri
        self.material = material
        frames, twice_area = edge_frames(points, tri)
        scale = np.ptp(points[np.unique(tri)], axis=0).max() if points.size else 0.0
        bad = ~(twice_area > 1e-12 * max(scale, 1e-300) ** 2)
        if np.any(bad):
            raise ModelError(
                f"{int(bad.sum())} triangle(s) have no area (first: triangle {int(np.argmax(bad))})"
            )
        self.rest_frames = frames
        self.areas = 0.5 * twice_area
        # The rest triangle in its frame: local (t, 3 nodes, 3) with node a at the origin.
        self.rest_local = np.einsum("tji,taj->tai", frames, points[tri] - points[tri][:, :1])
        self._d = material.plane_stress_matrix()
        self._weight = (self.areas * material.thickness)[:, None, None]
        self.k0 = self._stiffness(self.rest_local)
        self.dofs = (3 * tri[:, :, None] + np.arange(3)).reshape(-1, 9)
        self.rest_points = points

    @property
    def volumes(self) -> np.ndarray:
        """Area times thickness of each triangle (t,)."""
        return self.areas * self.material.thickness

    def _stiffness(self, local: np.ndarray) -> np.ndarray:
        """A0 t B^T D B (t, 9, 9) in the elements' frames, B the strain-displacement matrix of
        the triangles `local` (t, 3 nodes, 3; node a at the origin, b on the x axis)."""
        bx, cx, cy = local[:, 1, 0], local[:, 2, 0], local[:, 2, 1]
        g = np.zeros((local.shape[0], 3, 2))  # shape-function gradients in the plane
        g[:, 0] = np.stack([-1.0 / bx, (cx - bx) / (bx * cy)], axis=1)
        g[:, 1] = np.stack([1.0 / bx, -cx / (bx * cy)], axis=1)
        g[:, 2, 1] = 1.0 / cy
        b = np.zeros((local.shape[0], 3, 3, 3))  # (strain, node, local component)
        b[:, 0, :, 0] = g[:, :, 0]
        b[:, 1, :, 1] = g[:, :, 1]
        b[:, 2, :, 0] = g[:, :, 1]
        b[:, 2, :, 1] = g[:, :, 0]
        b = b.reshape(-1, 3, 9)
        return self._weight * np.einsum("tsi,sr,trj->tij", b, self._d, b)

    def local_state(self, positions: np.ndarray) -> tuple:
        """At `positions`: the frames R (t, 3, 3), the current over rest areas (t,; 0 for a
        triangle collapsed to a line or a point, which keeps its rest frame and B), the local
        stiffnesses K (t, 9, 9; "large": of the current triangle, as SOFA's) and the local
        displacements u = R^T (x - x_a) - R0^T (X - X_a) (t, 9)."""
        x = positions[self.triangles]
        if self.material.method == "small":
            local = np.einsum("tji,taj->tai", self.rest_frames, x - x[:, :1])
            ratio = np.ones(self.triangles.shape[0])
            return self.rest_frames, ratio, self.k0, (local - self.rest_local).reshape(-1, 9)
        frames, twice_area = edge_frames(positions, self.triangles)
        ratio = twice_area / (2.0 * self.areas)
        flat = ~np.all(np.isfinite(frames), axis=(1, 2)) | ~(ratio > 1e-12)
        frames[flat] = self.rest_frames[flat]
        local = np.einsum("tji,taj->tai", frames, x - x[:, :1])
        stiffness = self.k0.copy()
        if not flat.all():
            stiffness[~flat] = self._stiffness(local[~flat])
        u = (local - self.rest_local).reshape(-1, 9)
        return frames, np.where(flat, 0.0, ratio), stiffness, u

    def element_forces(self, positions: np.ndarray) -> tuple[np.ndarray, float]:
        """(t, 3, 3) forces on each triangle's nodes and the elastic energy."""
        forces, energy, _, _ = self.forces_and_frames(positions)
        return forces, energy

    def forces_and_frames(self, positions: np.ndarray) -> tuple:
        """Forces (t, 3, 3), energy, frames (t, 3, 3) and area ratios (t,) at `positions`."""
        frames, ratio, stiffness, u = self.local_state(positions)
        local = np.einsum("tij,tj->ti", stiffness, u)
        energy = 0.5 * float(np.einsum("ti,ti->", u, local))
        forces = -np.einsum("tij,taj->tai", frames, local.reshape(-1, 3, 3))
        return forces, energy, frames, ratio

    def stiffness_blocks(self, positions: np.ndarray) -> np.ndarray:
        """R K R^T (t, 9, 9) at `positions`: SOFA's tangent."""
        frames, _, stiffness, _ = self.local_state(positions)
        k = stiffness.reshape(-1, 3, 3, 3, 3)
        k = np.einsum("tik,takbl,tjl->taibj", frames, k, frames)
        return k.reshape(-1, 9, 9)

    def element_stiffness(self, positions: np.ndarray) -> np.ndarray:
        """The tangent stiffness -df/dx (t, 9, 9) of each triangle (SOFA's R K R^T)."""
        return self.stiffness_blocks(positions)


class ShellBody(TetBody):
    """A deformable body of constant-strain triangles: SOFA's TriangleFEMForceField on a
    triangle topology (a shell, a membrane: no bending stiffness).

    Args:
        points: (n, 3) rest positions of the nodes (every node on a triangle).
        triangles: (t, 3) the shell's triangles (SOFA's order: the first edge gives a frame).
        material: :class:`PlaneStress` (E, nu, thickness, "large" or "small").
        mass: "uniform" (total mass / nodes, SOFA's UniformMass), "lumped" (rho A t / 3 on
            each node of a triangle), "consistent" (rho A t / 12 (1 + delta_ab)) or "none".

    The other keywords are those of :class:`pliant.fem.body.BodyOptions` (density per volume
    A t, or total mass; held nodes and DoFs, gravity, Rayleigh damping, loads, projections),
    and the body answers the solvers as :class:`pliant.fem.body.TetBody` does. It has no
    tetrahedra: what takes them (:mod:`pliant.diff`, :mod:`pliant.reduction`, membranes,
    per-node rotations) refuses it with a ModelError.
    """

    def __init__(
        self, points: np.ndarray, triangles: np.ndarray, material: PlaneStress, **options: Any
    ) -> None:
        points = np.ascontiguousarray(points, dtype=np.float64)
        if points.ndim != 2 or points.shape[1] != 3 or not np.all(np.isfinite(points)):
            raise ModelError(f"points must be a finite (n, 3) array, got shape {points.shape}")
        self.elements = TriangleFEM(points, triangles, material)
        unused = np.setdiff1d(np.arange(points.shape[0]), self.elements.triangles)
        if unused.size:
            raise ModelError(
                f"{unused.size} node(s) belong to no triangle (first: node {int(unused[0])}):"
                " they would make the stiffness singular"
            )
        self.material = material
        self.rest_positions = points
        self.triangles = self.elements.triangles
        self.volumes = self.elements.volumes
        self.frame_nodes = self.triangles
        self.rest_frames = self.elements.rest_frames
        n = self.triangles.shape[0]
        self.mu = np.full(n, material.mu)
        self.lam = np.full(n, material.lam)
        self._hold_and_weigh(self.triangles, BodyOptions(**options), ())

    @property
    def tets(self) -> np.ndarray:
        raise ModelError(
            "a shell of triangles (ShellBody) has no tetrahedra: this takes a body of"
            " tetrahedra (pliant.diff, pliant.reduction and per-node rotations do)"
        )

    @property
    def mesh(self):
        raise ModelError("a shell of triangles (ShellBody) has no tetrahedral mesh")

    # --- layout -----------------------------------------------------------------------------
    @property
    def element_nodes(self) -> np.ndarray:
        return self.triangles

    @property
    def label(self) -> str:
        return f"{self.triangles.shape[0]} triangles"

    @cached_property
    def boundary_triangles(self) -> np.ndarray:
        """The shell's own triangles (what touches and is drawn)."""
        return self.triangles

    def vtk_cells(self) -> tuple[str, np.ndarray, np.ndarray]:
        return "triangle", self.triangles, np.arange(self.n_nodes)

    def node_rotations(self, frames, reference, nodes):
        raise ModelError("per-node rotations are those of tetrahedra, not of a ShellBody")

    # --- mass -------------------------------------------------------------------------------
    def _element_mass(self) -> np.ndarray:
        """rho A t (t,) of each triangle."""
        return self.density * self.volumes

    def _node_masses(self, mass: str) -> np.ndarray:
        if mass == "uniform":
            return np.full(self.n_nodes, self.total_mass / self.n_nodes)
        if mass in ("lumped", "consistent"):
            out = np.zeros(self.n_nodes)
            np.add.at(out, self.triangles.ravel(), np.repeat(self._element_mass() / 3.0, 3))
            return out
        raise ModelError(f"mass must be 'lumped', 'uniform', 'consistent' or 'none', got {mass!r}")

    def _mass_data(self, mass: str) -> np.ndarray:
        if mass != "consistent":
            return super()._mass_data(mass)
        local = np.kron((np.ones((3, 3)) + np.eye(3)) / 12.0, np.eye(3))
        blocks = local[None] * self._element_mass()[:, None, None]
        data = np.zeros(self.pattern.nnz)
        kernels.scatter_add(np.ascontiguousarray(blocks), 1.0, self.pattern.scatter, data)
        return data

    # --- elasticity -------------------------------------------------------------------------
    def _element_forces(self, x: np.ndarray, v: np.ndarray) -> tuple:
        """Per-element forces (and K_s v when `v` has rows) side by side, (t, 3, 3 or 6), the
        energy, the frames and current / rest areas (0: a collapsed triangle)."""
        forces, energy, frames, ratio = self.elements.forces_and_frames(x)
        if not v.shape[0]:
            return np.ascontiguousarray(forces), energy, frames, ratio
        blocks = self.elements.stiffness_blocks(x)
        kv = np.einsum("trc,tc->tr", blocks, v[self.triangles].reshape(-1, 9))
        elem = np.concatenate([forces, kv.reshape(-1, 3, 3)], axis=2)
        return np.ascontiguousarray(elem), energy, frames, ratio

    def stiffness_matvec(
        self, lin: Linearisation, u: np.ndarray, *, exact: bool = False
    ) -> np.ndarray:
        """K_s u on the free DoFs (SOFA's R K0 R^T); u is (n_free,) or (n_free, k)."""
        cols = np.ascontiguousarray(u[:, None] if u.ndim == 1 else u, dtype=np.float64)
        blocks = self.elements.stiffness_blocks(lin.positions)
        dofs = self._elem_dofs
        local = np.where(dofs[:, :, None] >= 0, cols[dofs], 0.0)
        elem_out = np.einsum("trc,tck->trk", blocks, local).reshape(-1, 3, 3, cols.shape[1])
        out = np.empty_like(cols)
        kernels.gather_free(
            np.ascontiguousarray(elem_out),
            self._incidence_ptr,
            self._incidence,
            self.free_index,
            out,
        )
        self._add_surface_matvec(lin, cols, out)
        return out[:, 0] if u.ndim == 1 else out

    def stiffness_data(self, lin: Linearisation, *, exact: bool = False) -> np.ndarray:
        """Tangent stiffness on the free DoFs, as data aligned with `self.pattern`."""
        data = np.zeros(self.pattern.nnz)
        blocks = self.elements.stiffness_blocks(lin.positions)
        kernels.scatter_add(np.ascontiguousarray(blocks), 1.0, self.pattern.scatter, data)
        self._add_surface_data(lin, data)
        return data
