"""Springs between points carried by the body (EmbeddedSprings, SOFA's MeshSpringForceField
on barycentrically mapped points): forces, tangent and energy agree by finite differences; a
spring between two nodes is the closed-form linear spring; the body widens its stiffness
pattern for springs between elements and a static solve balances them."""

from __future__ import annotations

import numpy as np
import pytest

from pliant.constraints.base import EmbeddedPoints
from pliant.errors import ModelError
from pliant.fem.body import TetBody
from pliant.fem.loads import EmbeddedSprings
from pliant.fem.material import Corotational
from pliant.mesh import box_beam
from pliant.model import Model
from pliant.solvers import StaticSolver


@pytest.fixture(scope="module")
def mesh():
    return box_beam(40.0, 10.0, 10.0, 4, 1, 1)


def _springs(mesh, points, edges, k=3.0):
    embedded = EmbeddedPoints(mesh, points)
    return EmbeddedSprings(
        embedded.nodes, embedded.weights, edges, k, rest_positions=mesh.points
    ), embedded


def test_forces_and_tangent_are_the_energy_derivatives(mesh) -> None:
    points = np.array([[2.0, 3.0, 4.0], [37.0, 6.0, 5.0], [20.0, 1.0, 9.0]])
    load, _ = _springs(mesh, points, [0, 1, 1, 2])
    rng = np.random.default_rng(0)
    x = mesh.points + rng.normal(scale=1.5, size=mesh.points.shape)
    forces = load.forces(x)
    h = 1e-6
    numeric = np.zeros_like(x)
    for i in np.unique(load.groups):
        for c in range(3):
            dx = np.zeros_like(x)
            dx[i, c] = h
            numeric[i, c] = -(load.energy(x + dx) - load.energy(x - dx)) / (2 * h)
    assert np.abs(forces - numeric).max() < 1e-6 * np.abs(forces).max()
    # Tangent: K = -df/dx, assembled per group against central differences of the forces.
    u = rng.normal(size=x.shape)
    blocks = load.group_tangents(x, 0.0)
    ku = np.zeros_like(x)
    local = u[load.groups].reshape(len(load.groups), -1)
    np.add.at(
        ku, load.groups, np.einsum("grc,gc->gr", blocks, local).reshape(load.groups.shape + (3,))
    )
    fd = -(load.forces(x + h * u) - load.forces(x - h * u)) / (2 * h)
    assert np.abs(ku - fd).max() < 1e-6 * np.abs(fd).max()
    assert np.abs(blocks - blocks.transpose(0, 2, 1)).max() < 1e-12


def test_a_spring_between_two_nodes_is_the_linear_spring(mesh) -> None:
    """Points at nodes a, b: f_a = k (l - L) u, f_b = -f_a, nothing elsewhere; a point at an
    element's centre passes a quarter of its force to each of the element's nodes."""
    a, b = 0, mesh.n_nodes - 1
    load, _ = _springs(mesh, mesh.points[[a, b]], [0, 1], k=7.0)
    x = mesh.points.copy()
    x[b] += np.array([3.0, -1.0, 2.0])
    d = x[b] - x[a]
    rest = np.linalg.norm(mesh.points[b] - mesh.points[a])
    expected = 7.0 * (np.linalg.norm(d) - rest) * d / np.linalg.norm(d)
    f = load.forces(x)
    assert np.abs(f[a] - expected).max() < 1e-9 * np.abs(expected).max()
    assert np.abs(f[b] + expected).max() < 1e-9 * np.abs(expected).max()
    others = np.setdiff1d(np.arange(mesh.n_nodes), [a, b])
    assert np.abs(f[others]).max() < 1e-9 * np.abs(expected).max()
    centre = mesh.points[mesh.tets[0]].mean(axis=0)
    load, _ = _springs(mesh, np.array([centre, mesh.points[b]]), [0, 1], k=7.0)
    x = 1.1 * mesh.points  # stretched 10 %: the spring pulls with 0.1 k L
    f = load.forces(x)
    pull = 7.0 * 0.1 * np.linalg.norm(mesh.points[b] - centre)
    assert np.isclose(np.linalg.norm(f[mesh.tets[0]], axis=1), pull / 4).all()


def test_a_body_balances_a_prestressed_spring_between_elements(mesh) -> None:
    """Two points at the beam's ends, rest length 60 % of their distance: the static solve
    (clamped at x = 0) shortens the beam, and the spring's nodal forces sum to zero."""
    points = np.array([[1.0, 5.0, 5.0], [39.0, 5.0, 5.0]])
    embedded = EmbeddedPoints(mesh, points)
    load = EmbeddedSprings(embedded.nodes, embedded.weights, [0, 1], 50.0, rest_lengths=[22.8])
    clamp = np.flatnonzero(mesh.points[:, 0] < 1e-9)
    body = TetBody(mesh, Corotational(1000.0, 0.3), total_mass=1.0, fixed_nodes=clamp, loads=[load])
    state = StaticSolver(Model(body)).step(Model(body).rest_state())
    ends = embedded.positions(state.positions)
    length = np.linalg.norm(ends[1] - ends[0])
    assert 22.8 < length < 38.0
    assert np.abs(load.forces(state.positions).sum(axis=0)).max() < 1e-9


def test_springs_refuse_bad_input(mesh) -> None:
    embedded = EmbeddedPoints(mesh, mesh.points[:2])
    with pytest.raises(ModelError, match="stiffness"):
        EmbeddedSprings(embedded.nodes, embedded.weights, [0, 1], -1.0, rest_lengths=[1.0])
    with pytest.raises(ModelError, match="edge point indices"):
        EmbeddedSprings(embedded.nodes, embedded.weights, [0, 5], 1.0, rest_lengths=[1.0])
