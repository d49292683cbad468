"""Membranes of triangles bonded to a tetrahedral body: stiff in their plane, free to bend.

A strain-limiting layer (the paper under a pneumatic walker, a fabric skin) is far thinner than
the body's elements and far stiffer than its silicone. Stiffening the elements that hold it
cannot work on a coarse mesh: a single linear tetrahedron through the layer locks in bending,
so the layer resists curling as much as stretching. A membrane on the body's surface nodes
carries only the in-plane stretch, as SOFA's TriangleFEMForceField does for the Multigait's
paper layer.

Element: the constant-strain triangle with the St Venant-Kirchhoff law in plane stress,
psi = A (mu_s |E|^2 + lam_s/2 tr(E)^2), E = (F^T F - I) / 2, F (3 x 2) the map from the rest
triangle's plane; mu_s = Y / (2 (1 + nu)), lam_s = Y nu / (1 - nu^2) with Y = E_material t the
membrane's stretch stiffness (force per length). The tangent drops the compressive part of the
second Piola stress from its geometric term (a membrane under compression wrinkles instead of
resisting), which keeps it positive semi-definite.

Fibres (optional): inextensible-ish threads wound in the membrane's plane along a direction a
per triangle (a fibre-reinforced chamber's hoop winding) add psi_f = A Y_f / 2 (a^T E a)^2,
so S_f = Y_f (a^T E a) a a^T; the threads resist stretch along a only, and the wall stays
free to stretch across them (a chamber elongates instead of ballooning).
"""

from __future__ import annotations

import math

import numpy as np
import scipy.sparse as sp

from pliant.errors import MaterialError, ModelError


class Membrane:
    """A membrane of triangles on nodes of a body.

    Args:
        points: (n, 3) rest positions of the body's nodes.
        triangles: (t, 3) node indices of the membrane's triangles (non-degenerate).
        stretch_stiffness: Young's modulus times thickness, Y = E t > 0 (force per length:
            kPa mm = N/m in mm-kg-s scenes).
        poisson_ratio: in-plane Poisson ratio, 0 <= nu < 1 (plane stress).
        fibres: (t, 3) a direction per triangle (projected onto its plane) of fibres of
            stretch stiffness `fibre_stiffness` (force per length), or None.
    """

    # Its triangles are faces of the body's tetrahedra (a pair of nodes that share none is
    # refused); a shell's (pliant.fem.shell.TriangleFEM) may span nodes of no tetrahedron.
    spans_elements = False

    def __init__(
        self,
        points: np.ndarray,
        triangles: np.ndarray,
        *,
        stretch_stiffness: float,
        poisson_ratio: float,
        fibres: np.ndarray | None = None,
        fibre_stiffness: float = 0.0,
    ) -> None:
        y, nu = stretch_stiffness, poisson_ratio
        if not (math.isfinite(y) and y > 0):
            raise MaterialError(f"a membrane's stretch stiffness must be > 0, got {y!r}")
        if not (math.isfinite(nu) and 0 <= nu < 1):
            raise MaterialError(f"a membrane's Poisson ratio must lie in [0, 1), got {nu!r}")
        self.triangles = np.ascontiguousarray(triangles, dtype=np.int64).reshape(-1, 3)
        self.mu = y / (2.0 * (1.0 + nu))
        self.lam = y * nu / (1.0 - nu * nu)
        rest = np.asarray(points, dtype=float)[self.triangles]
        e1, e2 = rest[:, 1] - rest[:, 0], rest[:, 2] - rest[:, 0]
        normal = np.cross(e1, e2)
        twice_area = np.linalg.norm(normal, axis=1)
        scale = np.linalg.norm(e1, axis=1) * np.linalg.norm(e2, axis=1)
        if np.any(twice_area <= 1e-12 * scale):
            raise ModelError("a membrane triangle is degenerate (zero area)")
        self.areas = 0.5 * twice_area
        # An orthonormal frame (u, w) of each triangle's plane; D holds the edges in it.
        u = e1 / np.linalg.norm(e1, axis=1)[:, None]
        w = np.cross(normal / twice_area[:, None], u)
        d = np.empty((len(self.triangles), 2, 2))
        d[:, 0, 0], d[:, 0, 1] = (e1 * u).sum(axis=1), (e2 * u).sum(axis=1)
        d[:, 1, 0], d[:, 1, 1] = 0.0, (e2 * w).sum(axis=1)
        d_inv = np.linalg.inv(d)
        # F = sum_a x_a g_a^T, g_a the gradient of node a's shape function in the plane.
        self.grads = np.stack([-d_inv[:, 0] - d_inv[:, 1], d_inv[:, 0], d_inv[:, 1]], axis=1)
        self.dofs = (3 * self.triangles[:, :, None] + np.arange(3)).reshape(-1, 9)
        self.fibre_stiffness = float(fibre_stiffness)
        if not (math.isfinite(self.fibre_stiffness) and self.fibre_stiffness >= 0):
            raise MaterialError(f"a fibre stiffness must be >= 0, got {fibre_stiffness!r}")
        self.fibres = None
        if fibres is not None and self.fibre_stiffness > 0:
            a = np.asarray(fibres, dtype=float).reshape(-1, 3)
            if a.shape[0] != len(self.triangles):
                raise ModelError(f"fibres need one direction per triangle, got {a.shape}")
            plane = np.column_stack([(a * u).sum(axis=1), (a * w).sum(axis=1)])
            length = np.linalg.norm(plane, axis=1)
            if np.any(length <= 1e-9 * np.linalg.norm(a, axis=1)) or not np.all(
                np.isfinite(length)
            ):
                raise ModelError("a fibre direction is normal to its triangle (or not finite)")
            self.fibres = plane / length[:, None]

    def deformation_gradients(self, positions: np.ndarray) -> np.ndarray:
        """(t, 3, 2) F of each triangle at `positions` (n, 3)."""
        return np.einsum("tai,taj->tij", positions[self.triangles], self.grads)

    def _stress(self, f: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Green strain and second Piola stress (t, 2, 2)."""
        strain = 0.5 * (np.einsum("tki,tkj->tij", f, f) - np.eye(2))
        trace = strain[:, 0, 0] + strain[:, 1, 1]
        stress = 2.0 * self.mu * strain + self.lam * trace[:, None, None] * np.eye(2)
        if self.fibres is not None:
            a = self.fibres
            stretch = np.einsum("ti,tij,tj->t", a, strain, a)
            stress += self.fibre_stiffness * stretch[:, None, None] * np.einsum("ti,tj->tij", a, a)
        return strain, stress

    def element_forces(self, positions: np.ndarray) -> tuple[np.ndarray, float]:
        """(t, 3, 3) forces on each triangle's nodes, -A P g_a with P = F S, and the energy."""
        f = self.deformation_gradients(positions)
        strain, stress = self._stress(f)
        piola = f @ stress
        forces = -self.areas[:, None, None] * np.einsum("tij,taj->tai", piola, self.grads)
        trace = strain[:, 0, 0] + strain[:, 1, 1]
        density = self.mu * (strain * strain).sum(axis=(1, 2)) + 0.5 * self.lam * trace**2
        if self.fibres is not None:
            stretch = np.einsum("ti,tij,tj->t", self.fibres, strain, self.fibres)
            density = density + 0.5 * self.fibre_stiffness * stretch**2
        return forces, float(self.areas @ density)

    def element_stiffness(self, positions: np.ndarray) -> np.ndarray:
        """(t, 9, 9) tangent stiffness -df/dx of each triangle, node-major (a, i).

        K[a i, b j] = A (g_a^T S+ g_b delta_ij + F_ik dS_kl[b j] g_a,l), with
        dS[b j] = 2 mu sym(F^T e_j g_b^T) + lam tr(F^T e_j g_b^T) I and S+ the tensile part
        of S (the exact geometric term with S in tension).
        """
        f = self.deformation_gradients(positions)
        _, stress = self._stress(f)
        values, vectors = np.linalg.eigh(stress)
        tensile = np.einsum("tij,tj,tkj->tik", vectors, np.maximum(values, 0.0), vectors)
        g = self.grads
        geometric = np.einsum("tak,tkl,tbl->tab", g, tensile, g)
        k = np.einsum("tab,ij->taibj", geometric, np.eye(3))
        # F^T dF for dF = e_j g_b^T: (F^T dF)_kl = F_jk g_b,l.
        fg = np.einsum("tjk,tbl->tbjkl", f, g)
        trace = np.einsum("tbjkk->tbj", fg)
        d_stress = self.mu * (fg + np.swapaxes(fg, -1, -2))
        d_stress += self.lam * trace[..., None, None] * np.eye(2)
        if self.fibres is not None:
            a = self.fibres
            # d(a^T E a) = a^T sym(F^T dF) a = a^T (F^T dF) a.
            d_stretch = np.einsum("tk,tbjkl,tl->tbj", a, fg, a)
            d_stress += self.fibre_stiffness * np.einsum("tbj,tk,tl->tbjkl", d_stretch, a, a)
        d_piola = np.einsum("tik,tbjkl->tbjil", f, d_stress)
        k += np.einsum("tbjil,tal->taibj", d_piola, g)
        return self.areas[:, None, None] * k.reshape(-1, 9, 9)


class MembraneAssembly:
    """Where a membrane's element vectors and matrices go in a body's nodal arrays and its
    stiffness pattern (built once, by the body)."""

    def __init__(self, membrane: Membrane, n_nodes: int, free_index: np.ndarray, pattern) -> None:
        self.membrane = membrane
        if membrane.triangles.size and (
            membrane.triangles.min() < 0 or membrane.triangles.max() >= n_nodes
        ):
            raise ModelError(f"membrane node indices must lie in [0, {n_nodes})")
        dofs = membrane.dofs
        # Element vector (t, 9) -> nodal (3 n,): a sum over the triangles of each DoF.
        cols = np.arange(dofs.size)
        self.to_nodes = sp.csr_matrix(
            (np.ones(dofs.size), (dofs.ravel(), cols)), shape=(3 * n_nodes, dofs.size)
        )
        self.free_dofs = free_index[dofs]
        # Positions of the (row, column) entries in the pattern's data; every pair of a
        # triangle's nodes is an edge of the tetrahedral mesh when the triangles are faces.
        self.to_free, self.valid, self.positions = pattern.place(
            self.free_dofs, "a membrane triangle joins nodes that share no tetrahedron"
        )

    def nodal(self, elements: np.ndarray) -> np.ndarray:
        """(n, 3) sums of element vectors (t, 3, 3) or (t, 9)."""
        return (self.to_nodes @ elements.reshape(-1)).reshape(-1, 3)

    def add_to_data(self, blocks: np.ndarray, data: np.ndarray) -> None:
        """data += the element matrices (t, 9, 9), at their pattern positions."""
        data += np.bincount(self.positions, weights=blocks[self.valid], minlength=data.size)

    def matvec(self, blocks: np.ndarray, u: np.ndarray) -> np.ndarray:
        """K u on the free DoFs for u (n_free, k)."""
        local = np.where(self.free_dofs[:, :, None] >= 0, u[self.free_dofs], 0.0)
        products = np.einsum("trc,tck->trk", blocks, local)
        return self.to_free @ products.reshape(-1, u.shape[1])
