"""The tetrahedral mesh every Pliant body is built from."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class TetMesh:
    """A linear tetrahedral mesh.

    Attributes:
        points: (n, 3) float64 node coordinates, in the user's length unit (robots use mm).
        tets: (m, 4) int64 node indices; every element has positive signed volume
            ((p1 - p0) x (p2 - p0)) . (p3 - p0) > 0.
        surfaces: named triangle sets, (k, 3) int64 node indices with outward normals by the
            right-hand rule (for a cavity: pointing out of the enclosed fluid volume into the
            material is *inward* for the cavity; cavity surfaces are stored with normals pointing
            into the cavity's complement, i.e. such that their enclosed volume is positive).
        landmarks: named point sets, (k, 3) float64, in mesh coordinates: cable paths, pull
            points, effector points, fixed boxes as [[xmin, ymin, zmin], [xmax, ymax, zmax]].
    """

    points: np.ndarray
    tets: np.ndarray
    surfaces: dict[str, np.ndarray] = field(default_factory=dict)
    landmarks: dict[str, np.ndarray] = field(default_factory=dict)

    @property
    def n_nodes(self) -> int:
        return int(self.points.shape[0])

    @property
    def n_tets(self) -> int:
        return int(self.tets.shape[0])

    def signed_volumes(self) -> np.ndarray:
        """Signed volume of each tetrahedron, (m,)."""
        p = self.points[self.tets]
        e1, e2, e3 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0], p[:, 3] - p[:, 0]
        return np.einsum("ij,ij->i", np.cross(e1, e2), e3) / 6.0

    def boundary_triangles(self) -> np.ndarray:
        """Boundary faces (k, 3), oriented with outward normals."""
        t = self.tets
        # Faces opposite each vertex, ordered so that their normal points away from it.
        faces = np.concatenate(
            [t[:, [1, 2, 3]], t[:, [0, 3, 2]], t[:, [0, 1, 3]], t[:, [0, 2, 1]]], axis=0
        )
        key = np.sort(faces, axis=1)
        _, inverse, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
        return faces[counts[inverse.ravel()] == 1]
