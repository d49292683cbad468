"""Verification of the shell of constant-strain triangles (SOFA's TriangleFEMForceField):
the patch test under uniform tension, rigid motions, finite differences of energy, forces
and tangent, masses, a step, and the refusals of what a shell cannot do."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from pliant.diff.step import check_model
from pliant.errors import MaterialError, ModelError
from pliant.fem.loads import NodalForces
from pliant.fem.shell import PlaneStress, ShellBody, TriangleFEM
from pliant.model import Model, State
from pliant.solvers import ImplicitEuler, StaticSolver

E, NU, T = 400.0, 0.3, 0.5  # kPa, -, mm
L, W = 20.0, 10.0  # the patch, mm
METHODS = ("large", "small")


def _patch(nx: int = 4, ny: int = 3, jitter: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """An L x W rectangle in the plane z = 0 cut in 2 nx ny triangles (interior nodes moved
    by `jitter` of a cell, so that no two triangles are alike)."""
    xs, ys = np.meshgrid(np.linspace(0, L, nx + 1), np.linspace(0, W, ny + 1), indexing="ij")
    points = np.column_stack([xs.ravel(), ys.ravel(), np.zeros(xs.size)])
    inner = (xs.ravel() > 0) & (xs.ravel() < L) & (ys.ravel() > 0) & (ys.ravel() < W)
    shift = np.random.default_rng(7).uniform(-1, 1, (int(inner.sum()), 2))
    points[inner, :2] += jitter * shift * [L / nx, W / ny]
    node = np.arange(points.shape[0]).reshape(nx + 1, ny + 1)
    a, b, c, d = node[:-1, :-1], node[1:, :-1], node[1:, 1:], node[:-1, 1:]
    tri = np.concatenate([np.stack([a, b, c], -1), np.stack([a, c, d], -1)]).reshape(-1, 3)
    return points, tri


def _edge_tension(points: np.ndarray, sigma: float) -> np.ndarray:
    """Nodal forces (n, 3) of a uniform traction sigma along +x on the edge x = L (each
    segment's sigma t h split in halves)."""
    forces = np.zeros_like(points)
    edge = np.flatnonzero(np.isclose(points[:, 0], L))
    edge = edge[np.argsort(points[edge, 1])]
    for i, j in zip(edge[:-1], edge[1:], strict=True):
        share = 0.5 * sigma * T * np.linalg.norm(points[j] - points[i])
        forces[[i, j], 0] += share
    return forces


def _patch_error(method: str, sigma: float) -> float:
    """Largest departure of a pulled patch's static displacement from the uniform stress's."""
    points, tri = _patch(jitter=0.25)
    left = np.flatnonzero(np.isclose(points[:, 0], 0.0))
    corner = left[np.argmin(points[left, 1])]
    held = np.concatenate([3 * left, [3 * corner + 1], 3 * np.arange(len(points)) + 2])
    body = ShellBody(
        points,
        tri,
        PlaneStress(E, NU, thickness=T, method=method),
        density=1e-6,
        fixed_dofs=held,
        loads=[NodalForces(np.arange(len(points)), _edge_tension(points, sigma))],
    )
    model = Model(body)
    state = StaticSolver(model).step(model.rest_state())
    strain = sigma / E
    expected = points * [strain, -NU * strain, 0.0]
    return float(np.abs(state.positions - points - expected).max())


def test_patch_under_uniform_tension() -> None:
    """A patch of distorted triangles pulled by a uniform traction sigma on one edge, held on
    the opposite edge along x (one node along y too) and out of its plane: the linear
    element's displacement is the uniform stress's, u_x = sigma x / E, u_y = -nu sigma y / E,
    to round-off (the constant-strain triangle passes the patch test). The corotational
    element's frame follows each triangle's first edge, which the stretch turns where it is
    no principal direction: its departure is of second order, about 2 (sigma / E)^2 L (a
    quarter of it at half the stress)."""
    assert _patch_error("small", 2.0) < 1e-10 * L
    strain = 2.0 / E
    full, half = _patch_error("large", 2.0), _patch_error("large", 1.0)
    assert 1e-3 * strain * L < full < 3.0 * strain**2 * L
    assert 3.5 < full / half < 4.5


def test_uniform_stress_balances_in_any_orientation(rng) -> None:
    """The linear element in a plane turned anywhere in space: the exact displacement of the
    uniform stress balances the edge traction, turned alike, to round-off (the held edge
    carries the reaction: the forces sum to zero). The corotational element's forces turn
    with the body: at a deformed shape turned rigidly they are the unturned ones, turned."""
    points, tri = _patch(jitter=0.25)
    sigma, strain = 2.0, 2.0 / E
    deformed = points + points * [strain, -NU * strain, 0.0]
    rot = Rotation.from_rotvec([0.4, -1.1, 0.7]).as_matrix()
    shell = TriangleFEM(points @ rot.T, tri, PlaneStress(E, NU, thickness=T, method="small"))
    forces, _ = shell.element_forces(deformed @ rot.T)
    nodal = np.zeros_like(points)
    np.add.at(nodal, tri.ravel(), forces.reshape(-1, 3))
    inside = ~np.isclose(points[:, 0], 0.0)
    expected = -_edge_tension(points, sigma) @ rot.T
    np.testing.assert_allclose(nodal[inside], expected[inside], atol=1e-12 * sigma * T * W)
    assert np.abs(nodal.sum(axis=0)).max() < 1e-12 * sigma * T * W
    large = TriangleFEM(points, tri, PlaneStress(E, NU, thickness=T))
    x = points + 0.2 * rng.standard_normal(points.shape)
    forces, energy = large.element_forces(x)
    turned, turned_energy = large.element_forces(x @ rot.T + [1.0, 2.0, 3.0])
    np.testing.assert_allclose(turned, forces @ rot.T, atol=1e-10 * np.abs(forces).max())
    assert turned_energy == pytest.approx(energy, rel=1e-10)


def test_large_forces_are_sofas(rng) -> None:
    """The corotational force is SOFA's TriangleFEMForceField "large" force, written out here
    element by element as SOFA computes it: the edge frame R of the current triangle, the
    local displacement D = (rest - current) in it, J the strain-displacement matrix of the
    current local triangle, F = J (A0 t D_mat) J^T D, turned back by R (to 1e-12 at strains
    up to 5 %)."""
    points, tri = _patch(jitter=0.25)
    material = PlaneStress(E, NU, thickness=T)
    shell = TriangleFEM(points, tri, material)
    d_mat = material.plane_stress_matrix()
    for strain in (1e-3, 5e-2):
        noise = strain * rng.standard_normal(points.shape) * [1.0, 1.0, 0.5]
        x = points * [1 + strain, 1 - 0.3 * strain, 1.0] + noise
        ours, _ = shell.element_forces(x)
        for e, (a, b, c) in enumerate(tri):
            ex = (x[b] - x[a]) / np.linalg.norm(x[b] - x[a])
            ez = np.cross(ex, x[c] - x[a])
            ez /= np.linalg.norm(ez)
            r = np.array([ex, np.cross(ez, ex), ez])  # rows: world -> local
            bx, cx, cy = (r @ (x[b] - x[a]))[0], *(r @ (x[c] - x[a]))[:2]
            rest = shell.rest_local[e]
            disp = np.array([0, 0, rest[1, 0] - bx, 0, rest[2, 0] - cx, rest[2, 1] - cy])
            det = bx * cy
            j = np.zeros((6, 3))
            j[0, 0] = j[1, 2] = -cy / det
            j[0, 2] = j[1, 1] = (cx - bx) / det
            j[2, 0] = j[3, 2] = cy / det
            j[2, 2] = j[3, 1] = -cx / det
            j[4, 2] = j[5, 1] = bx / det
            f = j @ (d_mat * shell.areas[e] * T) @ j.T @ disp
            sofa = np.column_stack([f.reshape(3, 2), np.zeros(3)]) @ r
            assert np.abs(ours[e] - sofa).max() < 1e-12 * np.abs(ours).max()


@pytest.mark.parametrize("method", METHODS)
def test_rigid_motion(method) -> None:
    """The corotational element feels no force and stores no energy under any rigid motion;
    the linear one only under translations (a turn strains it)."""
    points, tri = _patch(jitter=0.25)
    shell = TriangleFEM(points, tri, PlaneStress(E, NU, thickness=T, method=method))
    rot = Rotation.from_rotvec([0.4, -1.1, 0.7]).as_matrix()
    scale = np.abs(shell.element_forces(points * 1.01)[0]).max()
    shifted, energy = shell.element_forces(points + [3.0, -2.0, 5.0])
    assert np.abs(shifted).max() < 1e-12 * scale and energy < 1e-20
    turned, energy = shell.element_forces(points @ rot.T + [3.0, -2.0, 5.0])
    if method == "large":
        assert np.abs(turned).max() < 1e-10 * scale and energy < 1e-16 * scale * L
    else:
        assert np.abs(turned).max() > 10 * scale


def test_forces_and_tangent_match_differences(rng) -> None:
    """f = -dE/dx and K = -df/dx by central differences: everywhere for the linear element;
    for the corotational one the tangent R K0 R^T is exact at any turned rest shape and the
    energy's derivative matches the force to the strain's order (SOFA's force is no exact
    gradient: its frame and B follow the triangle)."""
    points, tri = _patch(jitter=0.25)
    rot = Rotation.from_rotvec([0.4, -1.1, 0.7]).as_matrix()
    eps = 1e-6
    for method, x, rel_energy in (
        ("small", points + 0.3 * rng.standard_normal(points.shape), 1e-7),
        ("large", points @ rot.T, None),
        (
            "large",
            (points * [1.001, 0.999, 1.0] + 1e-3 * rng.standard_normal(points.shape)) @ rot.T,
            5e-3,
        ),
    ):
        shell = TriangleFEM(points, tri, PlaneStress(E, NU, thickness=T, method=method))
        forces, _ = shell.element_forces(x)
        tangent = shell.element_stiffness(x)
        for _ in range(3):
            d = rng.standard_normal(x.shape)
            local = d[tri].reshape(-1, 9)
            plus, minus = (shell.element_forces(x + s * eps * d) for s in (1, -1))
            if rel_energy is not None:
                fd = (plus[1] - minus[1]) / (2 * eps)
                assert fd == pytest.approx(-np.sum(forces.reshape(-1, 9) * local), rel=rel_energy)
            if method == "small" or rel_energy is None:
                ku = np.einsum("trc,tc->tr", tangent, local)
                fd_ku = -(plus[0] - minus[0]).reshape(-1, 9) / (2 * eps)
                assert np.linalg.norm(ku - fd_ku) < 1e-6 * np.linalg.norm(fd_ku)


@pytest.mark.parametrize("mass", ["uniform", "lumped", "consistent"])
def test_masses_and_free_fall(mass) -> None:
    """Every mass sums to the total (A t rho), and a free shell falls: one implicit Euler step
    from rest moves every node by g h^2 and leaves it unstrained."""
    points, tri = _patch(2, 2)
    total = 3.0
    body = ShellBody(
        points,
        tri,
        PlaneStress(E, NU, thickness=T),
        total_mass=total,
        mass=mass,
        gravity=(0.0, -9810.0, 0.0),
    )
    assert body.node_masses.sum() == pytest.approx(total, rel=1e-12)
    assert body.density == pytest.approx(total / (L * W * T), rel=1e-12)
    ones = np.zeros((body.n_nodes, 3))
    ones[:, 1] = 1.0
    assert body.mass_matvec(body.gather(ones)).sum() == pytest.approx(total, rel=1e-12)
    model = Model(body)
    h = 0.01
    state = ImplicitEuler(model, h).step(model.rest_state())
    fall = np.broadcast_to([0.0, -9810.0 * h * h, 0.0], points.shape)
    np.testing.assert_allclose(state.positions - points, fall, atol=1e-9)


def test_assembled_stiffness_and_stretched_step(rng) -> None:
    """The body's sparse tangent equals its element blocks summed, its matrix-free product
    equals the matrix's, and a patch held on one edge and stretched springs back towards
    rest under implicit Euler."""
    points, tri = _patch(3, 2, jitter=0.2)
    left = np.flatnonzero(np.isclose(points[:, 0], 0.0))
    body = ShellBody(
        points, tri, PlaneStress(E, NU, thickness=T), total_mass=1e-3, fixed_nodes=left
    )
    x = (points * [1.05, 1.0, 1.0]) @ Rotation.from_rotvec([0, 0, 0.2]).as_matrix().T
    x[left] = points[left]
    lin = body.linearise(x)
    dense = np.zeros((3 * body.n_nodes,) * 2)
    for dofs, block in zip(body.elements.dofs, body.elements.element_stiffness(x), strict=True):
        dense[np.ix_(dofs, dofs)] += block
    free = body.free_dofs
    matrix = body.stiffness_matrix(lin).toarray()
    np.testing.assert_allclose(matrix, dense[np.ix_(free, free)], atol=1e-12 * np.abs(dense).max())
    u = rng.standard_normal((body.n_free, 2))
    np.testing.assert_allclose(body.stiffness_matvec(lin, u), matrix @ u, atol=1e-9)
    model = Model(body)
    state = State(x, np.zeros_like(x))
    stretch = np.ptp(state.positions[:, 0])
    for _ in range(3):
        state = ImplicitEuler(model, 0.01).step(state)
    assert np.all(np.isfinite(state.positions))
    assert np.ptp(state.positions[:, 0]) < stretch


def test_refusals() -> None:
    """A shell refuses what it cannot be: a thickness <= 0, an unknown method, a degenerate
    triangle, a node on no triangle; pliant.diff and the tools that take tetrahedra name it."""
    points, tri = _patch(2, 1)
    with pytest.raises(MaterialError, match="thickness"):
        PlaneStress(E, NU, thickness=0.0)
    with pytest.raises(MaterialError, match="method"):
        PlaneStress(E, NU, method="polar")
    flat = points.copy()
    flat[tri[0, 2]] = flat[tri[0, 0]]
    with pytest.raises(ModelError, match="no area"):
        TriangleFEM(flat, tri, PlaneStress(E, NU))
    with pytest.raises(ModelError, match="no triangle"):
        ShellBody(np.vstack([points, [[0, 0, 9.0]]]), tri, PlaneStress(E, NU), total_mass=1.0)
    body = ShellBody(points, tri, PlaneStress(E, NU), total_mass=1.0)
    with pytest.raises(ModelError, match="tetrahedra"):
        body.tets  # noqa: B018
    with pytest.raises(ModelError, match="corotational and Neo-Hookean"):
        check_model(Model(body))
