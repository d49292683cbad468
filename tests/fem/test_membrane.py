"""Verification of the membrane of triangles bonded to a tetrahedral body: closed-form energy
of affine stretches, finite-difference checks of forces and tangent, assembly into the body."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import clamped_body
from scipy.spatial.transform import Rotation

from pliant.errors import ModelError
from pliant.fem.body import TetBody
from pliant.fem.material import NeoHookean
from pliant.fem.membrane import Membrane
from pliant.mesh import box_beam

Y, NU = 5000.0, 0.3  # stretch stiffness E t (kPa mm) and in-plane Poisson ratio


@pytest.fixture
def slab():
    """A 20 x 10 x 2 mm slab and its underside triangles (z = 0)."""
    mesh = box_beam(20.0, 10.0, 2.0, 4, 2, 1)
    triangles = mesh.boundary_triangles()
    underside = triangles[np.all(mesh.points[triangles, 2] < 1e-9, axis=1)]
    return mesh, underside


def _membrane(slab) -> Membrane:
    mesh, underside = slab
    return Membrane(mesh.points, underside, stretch_stiffness=Y, poisson_ratio=NU)


def test_affine_stretch_energy_is_the_closed_form(slab) -> None:
    """x = F X on the plane z = 0: Green strain E = (F^T F - I) / 2 in every triangle, so the
    energy is A (mu |E|^2 + lam/2 tr(E)^2) with A = 200 mm^2 and the plane-stress Lamé
    parameters mu = Y / (2 (1 + nu)), lam = Y nu / (1 - nu^2)."""
    mesh, _ = slab
    membrane = _membrane(slab)
    f = np.array([[1.1, 0.05, 0.0], [-0.02, 0.95, 0.0], [0.0, 0.0, 1.0]])
    rotation = Rotation.from_rotvec([0.3, -0.2, 0.5]).as_matrix()
    x = mesh.points @ (rotation @ f).T
    strain = 0.5 * (f[:2, :2].T @ f[:2, :2] - np.eye(2))
    mu, lam = Y / (2 * (1 + NU)), Y * NU / (1 - NU**2)
    expected = 200.0 * (mu * np.sum(strain**2) + 0.5 * lam * np.trace(strain) ** 2)
    assert membrane.element_forces(x)[1] == pytest.approx(expected, rel=1e-12)
    # A rigid motion strains nothing.
    forces, energy = membrane.element_forces(mesh.points @ rotation.T + [1.0, 2.0, 3.0])
    assert energy < 1e-20 and np.abs(forces).max() < 1e-9


def test_forces_and_tangent_match_differences_in_tension(rng, slab) -> None:
    """f = -dE/dx and K u = -(f(x + e u) - f(x - e u)) / 2e + O(e^2) where every triangle is
    stretched (the tangent is exact there)."""
    mesh, _ = slab
    membrane = _membrane(slab)
    x = mesh.points * [1.05, 1.04, 1.0] + 0.05 * rng.standard_normal(mesh.points.shape)
    forces, _ = membrane.element_forces(x)
    tangent = membrane.element_stiffness(x)
    eps = 1e-5
    for _ in range(3):
        d = rng.standard_normal(x.shape)
        energies = [membrane.element_forces(x + s * eps * d)[1] for s in (1, -1)]
        fd = (energies[0] - energies[1]) / (2 * eps)
        local = d[membrane.triangles]
        assert fd == pytest.approx(-np.sum(forces * local), rel=1e-7)
        plus, minus = (membrane.element_forces(x + s * eps * d)[0] for s in (1, -1))
        ku = np.einsum("trc,tc->tr", tangent, local.reshape(-1, 9))
        fd_ku = -(plus - minus).reshape(-1, 9) / (2 * eps)
        assert np.linalg.norm(ku - fd_ku) < 1e-6 * np.linalg.norm(fd_ku)


def test_tangent_is_positive_semidefinite_in_compression(slab) -> None:
    """Compressed, a membrane wrinkles: the tangent keeps only the tensile stress in its
    geometric term, so no element matrix has a negative eigenvalue."""
    mesh, _ = slab
    membrane = _membrane(slab)
    tangent = membrane.element_stiffness(mesh.points * [0.8, 0.9, 1.0])
    assert np.linalg.eigvalsh(tangent).min() > -1e-9 * np.abs(tangent).max()


def test_body_with_a_membrane_assembles_it(rng, slab) -> None:
    """The body adds the membrane to its forces, energy and both tangent forms: assembled
    matrix = matrix-free product, symmetric, and K u matches force differences; stretching
    the slab along x costs more with the membrane."""
    mesh, underside = slab
    material = NeoHookean(70.0, 0.3)
    bare = clamped_body(mesh, material)
    body = clamped_body(mesh, material, membranes=[_membrane(slab)])
    x = mesh.points * [1.03, 1.02, 1.0] + 0.02 * rng.standard_normal(mesh.points.shape)
    x[body.fixed_nodes] = mesh.points[body.fixed_nodes]
    lin = body.linearise(x)
    assert lin.energy > bare.linearise(x).energy
    k = body.stiffness_matrix(lin).toarray()
    u = rng.standard_normal((body.n_free, 2))
    assert np.abs(k @ u - body.stiffness_matvec(lin, u)).max() < 1e-10 * np.abs(k @ u).max()
    assert np.abs(k - k.T).max() < 1e-12 * np.abs(k).max()
    eps = 1e-5
    du = body.scatter(u[:, 0])
    fd = -body.gather(body.linearise(x + eps * du).forces - body.linearise(x - eps * du).forces)
    fd /= 2 * eps
    assert np.linalg.norm(k @ u[:, 0] - fd) < 1e-6 * np.linalg.norm(fd)
    # Rayleigh damping's K v includes the membrane.
    v = body.scatter(u[:, 1])
    kv = body.gather(body.linearise(x, v).stiffness_velocity)
    assert np.allclose(kv, k @ u[:, 1], rtol=0, atol=1e-10 * np.abs(kv).max())


def test_a_membrane_off_the_mesh_edges_is_refused(slab) -> None:
    """Its triangles must be faces of the mesh: the stiffness pattern has room for no other."""
    mesh, _ = slab
    x = mesh.points
    corners = [
        int(np.argmin(x @ [1.0, 1.0, 1.0])),
        int(np.argmax(x[:, 0])),
        int(np.argmax(x[:, 1])),
    ]
    far = Membrane(x, np.array([corners]), stretch_stiffness=Y, poisson_ratio=NU)
    with pytest.raises(ModelError, match="share no tetrahedron"):
        TetBody(mesh, NeoHookean(70.0, 0.3), density=1e-6, membranes=[far])


def test_fibres_resist_stretch_along_them_only(rng, slab) -> None:
    """Fibres along x of stiffness Y_f add A Y_f / 2 (E_xx)^2 (closed form, A = 200 mm^2) and
    nothing to a stretch across them (E_xx = 0); forces and tangent = finite differences."""
    mesh, underside = slab
    y_f = 1e5
    membrane = Membrane(
        mesh.points,
        underside,
        stretch_stiffness=Y,
        poisson_ratio=NU,
        fibres=np.tile([1.0, 0.0, 0.0], (len(underside), 1)),
        fibre_stiffness=y_f,
    )
    plain = _membrane(slab)
    along = mesh.points * [1.1, 1.0, 1.0]
    e_xx = 0.5 * (1.1**2 - 1.0)
    extra = membrane.element_forces(along)[1] - plain.element_forces(along)[1]
    assert extra == pytest.approx(200.0 * 0.5 * y_f * e_xx**2, rel=1e-12)
    across = mesh.points * [1.0, 1.1, 1.0]
    assert membrane.element_forces(across)[1] == pytest.approx(plain.element_forces(across)[1])
    x = mesh.points * [1.05, 1.04, 1.0] + 0.05 * rng.standard_normal(mesh.points.shape)
    forces, _ = membrane.element_forces(x)
    tangent = membrane.element_stiffness(x)
    eps = 1e-5
    d = rng.standard_normal(x.shape)
    energies = [membrane.element_forces(x + s * eps * d)[1] for s in (1, -1)]
    local = d[membrane.triangles]
    assert (energies[0] - energies[1]) / (2 * eps) == pytest.approx(
        -np.sum(forces * local), rel=1e-7
    )
    plus, minus = (membrane.element_forces(x + s * eps * d)[0] for s in (1, -1))
    ku = np.einsum("trc,tc->tr", tangent, local.reshape(-1, 9))
    fd_ku = -(plus - minus).reshape(-1, 9) / (2 * eps)
    assert np.linalg.norm(ku - fd_ku) < 1e-6 * np.linalg.norm(fd_ku)
