"""Corotational trilinear hexahedra (SOFA's HexahedronFEMForceField) and hexahedral grids:
closed forms (a cantilever converging to Euler-Bernoulli, the uniaxial patch test), rigid
motions, the tangent against force differences, masses, and sparse grids against the surface
they voxelise."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse.linalg as spl
import trimesh
from scipy.spatial.transform import Rotation

from pliant.constraints.base import EmbeddedPoints
from pliant.errors import MaterialError, MeshError
from pliant.fem.hexbody import HexBody
from pliant.fem.loads import NodalForces
from pliant.fem.material import Corotational, NeoHookean
from pliant.mesh.hexmesh import HexMesh, regular_grid, sparse_grid
from pliant.model import Model
from pliant.solvers import StaticSolver

METHODS = ("large", "polar")


def _distorted_grid(rng, cells=(3, 2, 2), size=(30.0, 20.0, 20.0), amount=0.15) -> HexMesh:
    """A grid whose interior nodes are moved by up to `amount` of a cell: no element a box."""
    mesh = regular_grid(np.array(cells) + 1, (0.0, 0.0, 0.0), size)
    points = mesh.points.copy()
    step = np.array(size) / np.array(cells)
    inner = np.all((points > 1e-9) & (points < np.array(size) - 1e-9), axis=1)
    points[inner] += amount * step * rng.uniform(-1.0, 1.0, (int(inner.sum()), 3))
    return HexMesh(points, mesh.hexes)


@pytest.fixture(scope="module")
def distorted() -> HexMesh:
    return _distorted_grid(np.random.default_rng(7))


def _body(mesh: HexMesh, method: str, **kwargs) -> HexBody:
    return HexBody(mesh, Corotational(1000.0, 0.3, method), density=1e-3, **kwargs)


def _solve_linear(body: HexBody, forces: np.ndarray) -> np.ndarray:
    """Displacements of the linear problem K u = f at rest."""
    k = body.stiffness_matrix(body.linearise(body.rest_positions))
    return body.scatter(spl.spsolve(k.tocsc(), body.gather(forces[:, :, None])[:, 0]))


def test_cantilever_converges_to_euler_bernoulli() -> None:
    """A 100 x 10 x 10 cantilever (nu = 0, clamped end, shear negligible at L / h = 10 and
    beyond Euler-Bernoulli's 1 %) under a tip load: fully integrated trilinear elements are too
    stiff (they lock in bending), and the error falls with the cell size at order 2."""
    length, side, young, load = 100.0, 10.0, 1000.0, 0.01
    expected = load * length**3 / (3.0 * young * side**4 / 12.0)
    errors = []
    for cells in ((10, 1, 1), (20, 2, 2), (40, 4, 4)):
        mesh = regular_grid(np.array(cells) + 1, (0.0, 0.0, 0.0), (length, side, side))
        x = mesh.points
        body = HexBody(
            mesh,
            Corotational(young, 0.0, "large"),
            density=1.0,
            fixed_nodes=np.flatnonzero(x[:, 0] < 1e-9),
        )
        tip = np.flatnonzero(x[:, 0] > length - 1e-9)
        forces = np.zeros_like(x)
        forces[tip, 2] = -load / tip.size
        errors.append(-_solve_linear(body, forces)[tip, 2].mean() / expected - 1.0)
    errors = np.array(errors)
    assert np.all(errors < 0.0), errors  # too stiff
    assert np.all(np.diff(np.abs(errors)) < 0.0), errors
    assert abs(errors[-1]) < 0.03, errors  # measured -33 %, -10.7 %, -2.5 %
    assert np.log2(errors[1] / errors[2]) > 1.5, errors


@pytest.mark.parametrize("method", METHODS)
def test_uniaxial_patch_test_is_exact(method: str) -> None:
    """A bar pulled by a uniform traction on its end face, held only against rigid motions:
    the static solution is the uniform stretch sigma / E and the contraction -nu sigma / E,
    to round-off (the elements do not rotate, so the corotational problem is the linear one)."""
    size = np.array([30.0, 10.0, 10.0])
    mesh = regular_grid((4, 3, 3), (0.0, 0.0, 0.0), size)
    x = mesh.points
    young, nu, sigma = 1000.0, 0.3, 5.0
    left = np.flatnonzero(x[:, 0] < 1e-9)
    origin = int(np.flatnonzero(np.all(x < 1e-9, axis=1))[0])
    above = int(np.flatnonzero((x[:, 0] < 1e-9) & (x[:, 1] > 9.99) & (x[:, 2] < 1e-9))[0])
    held = np.concatenate([3 * left, [3 * origin + 1, 3 * origin + 2, 3 * above + 2]])
    # Consistent nodal forces of the traction: a quarter of each end face's area per corner.
    forces = np.zeros_like(x)
    for quad in mesh.boundary_quads():
        if np.all(x[quad, 0] > size[0] - 1e-9):
            area = np.linalg.norm(np.cross(x[quad[1]] - x[quad[0]], x[quad[3]] - x[quad[0]]))
            forces[quad, 0] += sigma * area / 4.0
    body = HexBody(
        mesh,
        Corotational(young, nu, method),
        density=1e-3,
        fixed_dofs=held,
        loads=[NodalForces(np.arange(len(x)), forces)],
    )
    model = Model(body)
    state = StaticSolver(model).step(model.rest_state())
    strain = sigma / young
    expected = x * np.array([strain, -nu * strain, -nu * strain])
    np.testing.assert_allclose(state.positions - x, expected, rtol=0, atol=1e-8 * strain * 30)


@pytest.mark.parametrize("method", METHODS)
def test_rigid_motions_give_no_force_and_forces_rotate_with_the_body(method, distorted) -> None:
    """At a rigid motion of the rest shape every force vanishes; at a deformed configuration
    moved rigidly the forces are the unmoved ones rotated (the corotational frame follows)."""
    body = _body(distorted, method)
    x = body.rest_positions
    rot = Rotation.from_rotvec([0.4, -1.1, 0.7]).as_matrix()
    shift = np.array([3.0, -2.0, 5.0])
    scale = np.abs(body.linearise(x * 1.01).forces).max()
    assert np.abs(body.linearise(x @ rot.T + shift).forces).max() < 1e-10 * scale
    deformed = x + 0.4 * np.random.default_rng(3).standard_normal(x.shape)
    lin = body.linearise(deformed)
    moved = body.linearise(deformed @ rot.T + shift)
    np.testing.assert_allclose(moved.forces, lin.forces @ rot.T, atol=1e-9 * scale)
    assert moved.energy == pytest.approx(lin.energy, rel=1e-10)
    assert lin.energy > 0.0 and np.isfinite(lin.forces).all()


@pytest.mark.parametrize("method", METHODS)
def test_tangent_matches_force_differences(method, distorted) -> None:
    """SOFA's tangent R K0 R^T is the derivative of the forces where the elements are
    unstrained (any rigid placement of the rest shape; elsewhere the rotation's variation,
    which SOFA leaves out, adds a term of the order of the strain), matrix and products agree
    and the matrix is symmetric."""
    rng = np.random.default_rng(11)
    body = _body(distorted, method, fixed_nodes=np.arange(4))
    rot = Rotation.from_rotvec([0.3, 0.9, -0.5]).as_matrix()
    x = body.rest_positions @ rot.T
    lin = body.linearise(x)
    u = rng.standard_normal(body.n_free)
    du, h = body.scatter(u), 1e-5
    plus, minus = body.linearise(x + h * du).forces, body.linearise(x - h * du).forces
    differences = -body.gather(((plus - minus) / (2.0 * h))[:, :, None])[:, 0]
    product = body.stiffness_matvec(lin, u)
    np.testing.assert_allclose(product, differences, atol=1e-6 * np.abs(product).max())
    matrix = body.stiffness_matrix(lin)
    np.testing.assert_allclose(matrix @ u, product, atol=1e-12 * np.abs(product).max())
    assert abs(matrix - matrix.T).max() < 1e-12 * abs(matrix).max()
    # Away from rest: the derivative of the forces with the rotations held.
    deformed = x + 0.3 * rng.standard_normal(x.shape)
    lin = body.linearise(deformed)
    held = np.zeros_like(x)
    for e, nodes in enumerate(body.hexes):
        r = lin.frames[e]
        d = (du[nodes] @ r).reshape(-1)  # R^T u per node
        held[nodes] += (body.k0[e] @ d).reshape(8, 3) @ r.T
    np.testing.assert_allclose(
        body.stiffness_matvec(lin, u), body.gather(held[:, :, None])[:, 0], atol=1e-10
    )


@pytest.mark.parametrize("mass", ["lumped", "uniform", "consistent"])
def test_masses_weigh_the_body(mass: str, distorted) -> None:
    """Every mass moves a rigid translation with the total mass rho V (V the grid's volume,
    distortion of the interior nodes does not change it)."""
    body = HexBody(distorted, Corotational(1000.0, 0.3), density=2.0, mass=mass)
    assert body.volumes.sum() == pytest.approx(30.0 * 20.0 * 20.0, rel=1e-12)
    ones = np.tile([1.0, 0.0, 0.0], body.n_nodes)
    assert body.mass_matvec(ones).sum() == pytest.approx(2.0 * 12000.0, rel=1e-12)
    assert body.gravity_forces().shape == (body.n_nodes, 3)


def test_hexahedra_refuse_other_materials_and_inverted_cells() -> None:
    mesh = regular_grid((2, 2, 2), (0.0, 0.0, 0.0), (1.0, 1.0, 1.0))
    with pytest.raises(MaterialError, match="corotational"):
        HexBody(mesh, NeoHookean(100.0, 0.3), density=1.0)
    with pytest.raises(MeshError, match="inverted"):
        HexMesh(mesh.points, mesh.hexes[:, [1, 0, 3, 2, 5, 4, 7, 6]])


def test_points_in_hexahedra_follow_the_trilinear_shape_functions(distorted) -> None:
    """Embedded points get eight weights that sum to one and give the point back, and follow
    an affine motion of the nodes exactly."""
    rng = np.random.default_rng(5)
    points = rng.uniform([1.0, 1.0, 1.0], [29.0, 19.0, 19.0], (20, 3))
    embedded = EmbeddedPoints(distorted, points)
    assert embedded.nodes.shape == (20, 8)
    np.testing.assert_allclose(embedded.weights.sum(axis=1), 1.0, atol=1e-12)
    np.testing.assert_allclose(embedded.positions(distorted.points), points, atol=1e-10)
    affine = rng.standard_normal((3, 3))
    moved = distorted.points @ affine.T
    np.testing.assert_allclose(embedded.positions(moved), points @ affine.T, atol=1e-9)


def test_a_sparse_grid_keeps_the_cells_the_surface_crosses_or_encloses() -> None:
    """SOFA's voxelisation of a sphere: every kept cell is crossed by the surface (weight 0.5)
    or lies inside it (weight 1, its centre inside); every dropped cell's centre is outside;
    nodes come sorted by x, then y, then z."""
    sphere = trimesh.creation.icosphere(subdivisions=3, radius=10.0)
    mesh, weights = sparse_grid(sphere.vertices, sphere.faces, (9, 9, 9))
    full = regular_grid((9, 9, 9), sphere.bounds[0] - 0.2, sphere.bounds[1] + 0.2)
    centres = mesh.points[mesh.hexes].mean(axis=1)
    inside = weights == 1.0
    assert set(np.unique(weights)) == {0.5, 1.0}
    assert sphere.contains(centres[inside]).all()
    kept = {tuple(np.round(c, 9)) for c in centres}
    all_centres = full.points[full.hexes].mean(axis=1)
    dropped = np.array([c for c in all_centres if tuple(np.round(c, 9)) not in kept])
    assert not sphere.contains(dropped).any()
    assert np.all(np.diff(mesh.points[:, 0]) >= 0.0)
    assert mesh.n_hexes < full.n_hexes
    assert np.all(weights[: int((~inside).sum())] == 0.5)  # boundary cells first
    # SOFA's virtual finer levels: the same cells or more, weights averaged from the finer.
    coarse, averaged = sparse_grid(sphere.vertices, sphere.faces, (9, 9, 9), finer_levels=1)
    assert coarse.n_hexes <= mesh.n_hexes and np.all((averaged > 0.0) & (averaged <= 1.0))
