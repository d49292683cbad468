"""TriangleMesh(winding=True): a point's side from the generalised winding number, which
agrees with the pseudo-normals on a surface that does not cross itself and stays right where
one overlaps itself."""

from __future__ import annotations

import numpy as np
from conftest import ball_surface

from pliant.geometry.collision import TriangleMesh


def _cube(centre, half):
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    faces = [
        [0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
        [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3],
    ]  # fmt: skip
    return np.asarray(centre) + half * corners, np.array(faces)


def test_winding_sign_agrees_with_pseudo_normals_on_a_closed_ball():
    rng = np.random.default_rng(3)
    vertices, faces = ball_surface(200, 1.0)
    points = rng.uniform(-1.5, 1.5, (300, 3))
    plain = TriangleMesh(vertices, faces).signed_distance(points)
    wound = TriangleMesh(vertices, faces, winding=True).signed_distance(points)
    np.testing.assert_array_equal(wound.gap, plain.gap)
    np.testing.assert_array_equal(wound.normal, plain.normal)


def test_winding_number_counts_overlapping_shells():
    """Two cubes overlapping in one mesh: winding 2 in their overlap, 1 in one, 0 outside;
    in the overlap the point is inside (gap < 0) whichever face is closest."""
    (va, fa), (vb, fb) = _cube((0, 0, 0), 1.0), _cube((1.5, 0, 0), 1.0)
    mesh = TriangleMesh(np.vstack([va, vb]), np.vstack([fa, fb + 8]), winding=True)
    points = np.array([[0.75, 0.0, 0.0], [-0.5, 0.0, 0.0], [3.0, 0.0, 0.0], [0.9, 0.99, 0.0]])
    np.testing.assert_allclose(mesh.winding_number(points), [2.0, 1.0, 0.0, 2.0], atol=1e-9)
    assert np.all(mesh.signed_distance(points[[0, 1, 3]]).gap < 0.0)
    assert mesh.signed_distance(points[[2]]).gap[0] > 0.0
