"""Mass properties of a closed triangle mesh (pliant.geometry.inertia.mesh_mass, the divergence
theorem): exact for a box, turned and moved, and converging to a solid sphere's closed forms as
its tessellation refines."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import ball_surface

from pliant.errors import ModelError
from pliant.geometry.collision import _box_surface
from pliant.geometry.inertia import box_inertia, mesh_mass, sphere_inertia
from pliant.geometry.rotation import axis_angle


def test_a_box_mesh_has_the_box_closed_forms() -> None:
    """A 2 x 4 x 6 box turned about (1, 2, 3) and moved to (5, -1, 2), density 2: volume 48,
    mass 96, centre (5, -1, 2), inertia R (m/3 diag(b^2+c^2, ...)) R^T, all to round-off."""
    half = np.array([1.0, 2.0, 3.0])
    vertices, faces = _box_surface(half, 1.0)  # faces split in cells: many triangles
    turn, shift = axis_angle([1.0, 2.0, 3.0], 0.7), np.array([5.0, -1.0, 2.0])
    solid = mesh_mass(vertices @ turn.T + shift, faces, 2.0)
    assert solid.volume == pytest.approx(48.0, rel=1e-12)
    assert solid.mass == pytest.approx(96.0, rel=1e-12)
    np.testing.assert_allclose(solid.centre, shift, rtol=0, atol=1e-12)
    expected = turn @ box_inertia(96.0, half) @ turn.T
    np.testing.assert_allclose(solid.inertia, expected, rtol=0, atol=1e-11)


def test_a_sphere_mesh_converges_to_the_solid_sphere() -> None:
    """Tessellated spheres of radius 2 (200, 800, 3200 vertices): the inscribed polyhedron's
    mass and inertia fall short of 4/3 pi r^3 rho and 2/5 m r^2 by an error that shrinks about
    as 1/n (the squared edge length), under 0.4 % at 3200 vertices; the centre is the
    sphere's."""
    radius, density, centre = 2.0, 3.0, np.array([1.0, 2.0, 3.0])
    mass = 4.0 / 3.0 * np.pi * radius**3 * density
    errors = []
    for n in (200, 800, 3200):
        solid = mesh_mass(*ball_surface(n, radius, centre), density)
        np.testing.assert_allclose(solid.centre, centre, atol=1e-3 * radius)
        inertia = np.diag(solid.inertia) / np.diag(sphere_inertia(mass, radius)) - 1.0
        errors.append((solid.mass / mass - 1.0, np.abs(inertia).max()))
    errors = np.array(errors)
    assert np.all(errors[:, 0] < 0.0)  # inscribed
    ratios = errors[:-1] / errors[1:]
    assert np.all((ratios[:, 0] > 3.0) & (ratios[:, 1] > 3.0))  # 4 times the vertices
    assert np.abs(errors[-1]).max() < 4e-3


def test_an_inward_mesh_is_refused() -> None:
    vertices, faces = _box_surface(np.ones(3), None)
    with pytest.raises(ModelError, match="oriented inwards"):
        mesh_mass(vertices, faces[:, ::-1])
