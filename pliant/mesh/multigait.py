"""The Multigait quadruped: a flat H-shaped pneumatic body with five sealed chambers.

Proportions follow the SoftRobots Multigait scene (Shepherd et al., PNAS 2011): a 136 x 58 mm
body 6.3 mm thick, a centre block between four legs, one chamber per leg and one in the
centre, 1 mm floors. The reference mesh of the SOFA scene (59k tetrahedra) is loaded with
:func:`pliant.mesh.load_mesh`; :func:`reference_cavity_surfaces` finds its chamber walls from
the scene's cavity surfaces.
"""

from __future__ import annotations

import gmsh
import numpy as np

from pliant.errors import MeshError
from pliant.mesh.gmsh_session import gmsh_model, mesh_volumes
from pliant.mesh.shapes import _cavity_surfaces, _finish, _require_positive
from pliant.mesh.tetmesh import TetMesh

CHAMBERS = ("centre", "front_left", "front_right", "rear_left", "rear_right")


def multigait_chambers(
    *,
    length: float = 136.0,
    width: float = 58.0,
    thickness: float = 6.3,
    leg_width: float = 16.0,
    centre_length: float = 46.0,
    wall: float = 3.0,
    floor: float = 1.0,
    roof: float = 1.5,
) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Lower and upper corners of each chamber (front is -x, left is +y)."""
    x0 = (length - centre_length) / 2
    x1 = x0 + centre_length
    y_in, y_out = width / 2 - leg_width + wall, width / 2 - wall
    z = (floor, thickness - roof)
    inner = width / 2 - leg_width - wall
    if not (y_in < y_out and inner > wall and x0 > 2 * wall and z[0] < z[1]):
        raise MeshError("walls, floor and roof leave no room for the Multigait's chambers")

    def chamber(xa: float, xb: float, ya: float, yb: float):
        return np.array([xa, ya, z[0]]), np.array([xb, yb, z[1]])

    reach = wall + 0.25 * centre_length  # leg chambers run into the centre block
    return {
        "centre": chamber(x0 + reach + wall, x1 - reach - wall, -inner, inner),
        "front_left": chamber(wall, x0 + reach, y_in, y_out),
        "front_right": chamber(wall, x0 + reach, -y_out, -y_in),
        "rear_left": chamber(x1 - reach, length - wall, y_in, y_out),
        "rear_right": chamber(x1 - reach, length - wall, -y_out, -y_in),
    }


def multigait(
    *,
    length: float = 136.0,
    width: float = 58.0,
    thickness: float = 6.3,
    leg_width: float = 16.0,
    centre_length: float = 46.0,
    wall: float = 3.0,
    floor: float = 1.0,
    roof: float = 1.5,
    mesh_size: float = 4.0,
) -> TetMesh:
    """The Multigait body along +x (front at x = 0), width along y (centred), underside z = 0.

    Surfaces: 'cavity_<chamber>' for the chambers of :data:`CHAMBERS`, walls oriented out of the
    air (positive enclosed volume). Landmarks: 'centre' (1, 3), the middle of the underside.
    """
    _require_positive(
        length=length,
        width=width,
        thickness=thickness,
        leg_width=leg_width,
        centre_length=centre_length,
        wall=wall,
        floor=floor,
        roof=roof,
        mesh_size=mesh_size,
    )
    chambers = multigait_chambers(
        length=length,
        width=width,
        thickness=thickness,
        leg_width=leg_width,
        centre_length=centre_length,
        wall=wall,
        floor=floor,
        roof=roof,
    )
    x0 = (length - centre_length) / 2
    with gmsh_model("multigait"):
        occ = gmsh.model.occ
        parts = [occ.addBox(x0, -width / 2, 0, centre_length, width, thickness)]
        for xa in (0.0, x0 + centre_length):
            for ya in (-width / 2, width / 2 - leg_width):
                parts.append(occ.addBox(xa, ya, 0, x0, leg_width, thickness))
        fused, _ = occ.fuse([(3, parts[0])], [(3, p) for p in parts[1:]])
        holes = [(3, occ.addBox(*lo, *(hi - lo))) for lo, hi in chambers.values()]
        occ.cut(fused, holes)
        occ.removeAllDuplicates()
        points, tets = mesh_volumes(mesh_size)
    found = _cavity_surfaces(points, tets, list(chambers.values()), tolerance=1e-6 * length)
    surfaces = {f"cavity_{name}": found[f"cavity_{n}"] for n, name in enumerate(chambers)}
    landmarks = {"centre": [length / 2, 0.0, 0.5 * floor]}
    return _finish(points, tets, landmarks, surfaces)


def reference_cavity_surfaces(
    mesh: TetMesh,
    cavity_surfaces: dict[str, TetMesh | tuple[np.ndarray, np.ndarray]],
    *,
    tolerance: float = 0.05,
) -> dict[str, np.ndarray]:
    """Chamber walls of a loaded mesh: its boundary triangles lying on each given closed
    surface (vertices, faces), e.g. the SOFA scene's cavity .stl files, oriented out of the air.

    Raises MeshError when a surface matches no boundary triangle or an open set of them.
    """
    from pliant.constraints.collision import TriangleMesh

    boundary = mesh.boundary_triangles()
    centres = mesh.points[boundary].mean(axis=1)
    out = {}
    for name, surface in cavity_surfaces.items():
        vertices, faces = surface
        shape = TriangleMesh(vertices, faces)
        on_wall = np.abs(shape.signed_distance(centres).gap) < tolerance
        if not on_wall.any():
            raise MeshError(f"no boundary triangle of the mesh lies on the {name} surface")
        out[name] = boundary[on_wall][:, [0, 2, 1]]
    return out
