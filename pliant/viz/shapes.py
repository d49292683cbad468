"""Triangulated surfaces of collision shapes, to draw obstacles and rigid bodies."""

from __future__ import annotations

import numpy as np

from pliant.geometry.collision import Box, Capsule, Plane, Shape, Sphere, TriangleMesh


def _uv_sphere(radius: float, n: int = 12) -> tuple[np.ndarray, np.ndarray]:
    """Latitude-longitude sphere (poles included), outward triangles."""
    theta = np.linspace(0.0, np.pi, n + 1)[1:-1]
    phi = np.linspace(0.0, 2 * np.pi, 2 * n, endpoint=False)
    t, p = np.meshgrid(theta, phi, indexing="ij")
    rings = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], axis=-1)
    points = radius * np.vstack([[0.0, 0.0, 1.0], rings.reshape(-1, 3), [0.0, 0.0, -1.0]])
    m = 2 * n
    idx = 1 + np.arange((n - 1) * m).reshape(n - 1, m)
    nxt = np.roll(idx, -1, axis=1)
    tris = [np.column_stack([np.zeros(m, int), idx[0], nxt[0]])]
    for r in range(n - 2):
        tris.append(np.column_stack([idx[r], idx[r + 1], nxt[r + 1]]))
        tris.append(np.column_stack([idx[r], nxt[r + 1], nxt[r]]))
    south = len(points) - 1
    tris.append(np.column_stack([np.full(m, south), nxt[-1], idx[-1]]))
    return points, np.vstack(tris)


def _box(half: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    corners = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)], float)
    faces = np.array(
        [
            [0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
            [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3],
        ]
    )  # fmt: skip
    return corners * half, faces


def shape_surface(
    shape: Shape,
    *,
    position: np.ndarray | None = None,
    rotation: np.ndarray | None = None,
    extent: float = 100.0,
    centre: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """World points and triangles of `shape` at its pose (or at `position`, `rotation`).

    A plane is drawn as a square of half side `extent` around the projection of `centre`.
    """
    x = shape.position if position is None else np.asarray(position, dtype=float)
    r = shape.rotation if rotation is None else np.asarray(rotation, dtype=float)
    if isinstance(shape, Plane):
        n = r[:, 2]
        c = np.zeros(3) if centre is None else np.asarray(centre, dtype=float)
        c = c - np.dot(c - x, n) * n
        # A grid rather than one quad: the painter's sort needs small faces to occlude well.
        n_cells = 10
        s = np.linspace(-extent, extent, n_cells + 1)
        a, b = np.meshgrid(s, s, indexing="ij")
        points = c + a.reshape(-1, 1) * r[:, 0] + b.reshape(-1, 1) * r[:, 1]
        k = np.arange(n_cells * (n_cells + 1)).reshape(n_cells, n_cells + 1)[:, :-1].ravel()
        nxt = k + n_cells + 1
        lower = np.column_stack([k, nxt, nxt + 1])
        return points, np.vstack([lower, np.column_stack([k, nxt + 1, k + 1])])
    if isinstance(shape, Sphere):
        local, faces = _uv_sphere(shape.radius)
    elif isinstance(shape, Box):
        local, faces = _box(shape.half_extents)
    elif isinstance(shape, Capsule):
        local, faces = _uv_sphere(shape.radius)
        local[:, 2] += np.sign(local[:, 2]) * shape.half_length
    elif isinstance(shape, TriangleMesh):
        local, faces = shape.vertices, shape.faces
    else:
        raise TypeError(f"no surface for a {type(shape).__name__}")
    return local @ r.T + x, faces
