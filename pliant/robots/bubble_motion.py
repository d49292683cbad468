"""BubbleMotion: a soft board with a 3 x 3 grid of pressure cavities under its top face moves
a ball lying on it (SofaGym bubblemotion-v0).

One deformable body, a square board (meshed with gmsh) held by its underside, with nine sealed
box cavities under a thin top skin. Inflating a cavity bulges the skin over it into a bubble;
a rigid ball resting on the board rolls off the bubbles, so that the pattern of pressures
steers it.
"""

from __future__ import annotations

import gmsh
import numpy as np

from pliant.constraints.base import EmbeddedPoints
from pliant.errors import ModelError
from pliant.fem.rigid import RigidBody
from pliant.geometry.collision import Plane, Sphere
from pliant.mesh.gmsh_session import gmsh_model, mesh_volumes, retry_meshing
from pliant.mesh.shapes import _cavity_surfaces, _finish, _require_positive, require_arguments
from pliant.mesh.tetmesh import TetMesh
from pliant.model import Model
from pliant.robots.common import cavity, fixed_by_box
from pliant.robots.parameters import Ball, Contact, Damping, Density, Gravity, Meshing, Solid
from pliant.robots.scene import builder

GRID = 3


def cavity_boxes(
    *, size: float, thickness: float, cavity: float, depth: float, skin: float
) -> list[tuple[np.ndarray, np.ndarray]]:
    """Lower and upper corners of the 9 cavities, row by row from (-x, -y): square `cavity` mm
    wide and `depth` deep, their tops `skin` mm under the board's top face, centred on a 3 x 3
    grid of pitch size / 3."""
    pitch = size / GRID
    if not (cavity < pitch and depth + skin < thickness):
        raise ModelError(
            f"cavities {cavity} mm wide and {depth} mm deep under a {skin} mm skin do not fit in"
            f" a {size} x {size} x {thickness} mm board ({GRID} x {GRID}, pitch {pitch:.3g} mm)"
        )
    top = thickness - skin
    centres = (np.arange(GRID) - (GRID - 1) / 2) * pitch
    return [
        (
            np.array([cx - cavity / 2, cy - cavity / 2, top - depth]),
            np.array([cx + cavity / 2, cy + cavity / 2, top]),
        )
        for cy in centres
        for cx in centres
    ]


@retry_meshing
def board_mesh(
    *,
    size: float = 60.0,
    thickness: float = 12.0,
    cavity: float = 14.0,
    depth: float = 5.0,
    skin: float = 2.0,
    mesh_size: float = 5.0,
    top_mesh_size: float = 2.0,
) -> TetMesh:
    """The board: x, y in [-size / 2, size / 2], z in [0, thickness], the 9 cavities of
    :func:`cavity_boxes` in it. Elements of about `mesh_size`, `top_mesh_size` on the top
    face: the ball touches the board's nodes, and between nodes `s` apart a ball of radius r
    sits in a hollow it leaves only on a slope steeper than about s / 2r.

    Surfaces: 'cavity_0..8' (row by row from (-x, -y), oriented out of the air) and 'cavity'
    (all). Landmarks: 'fixed_box' (the underside), 'top_<k>' (the top face over cavity k).
    """
    require_arguments(locals(), "size thickness cavity depth skin mesh_size top_mesh_size")
    boxes = cavity_boxes(size=size, thickness=thickness, cavity=cavity, depth=depth, skin=skin)
    half = size / 2
    with gmsh_model("bubble_board"):
        occ = gmsh.model.occ
        board = occ.addBox(-half, -half, 0.0, size, size, thickness)
        holes = [(3, occ.addBox(*lo, *(hi - lo))) for lo, hi in boxes]
        occ.cut([(3, board)], holes)
        occ.removeAllDuplicates()
        occ.synchronize()
        e = 1e-6 * size
        corners = gmsh.model.getEntitiesInBoundingBox(
            -half - e, -half - e, thickness - e, half + e, half + e, thickness + e, dim=0
        )
        gmsh.model.mesh.setSize(corners, min(top_mesh_size, mesh_size))
        points, tets = mesh_volumes(mesh_size)
    surfaces = _cavity_surfaces(points, tets, boxes, tolerance=1e-6 * size)
    landmarks = {"fixed_box": np.array([[-half - 1, -half - 1, -1.0], [half + 1, half + 1, 1e-6]])}
    for k, (lo, hi) in enumerate(boxes):
        landmarks[f"top_{k}"] = [(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, thickness]
    return _finish(points, tets, landmarks, surfaces)


@builder(
    Meshing(5.0),
    Solid(200.0, 0.45),
    Density(),
    Gravity.Z,
    Damping(1.0, 0.02),
    Contact(0.3, contact_margin=2.0),
    Ball(8.0, 0.002),
)
def bubble_motion(
    p,
    *,
    size: float = 60.0,
    thickness: float = 12.0,
    top_mesh_size: float = 2.0,
    max_pressure: float = 40.0,
    ball_position: tuple[float, float] = (0.0, 0.0),
) -> Model:
    """The board on the table and the ball on the board at (x, y) = `ball_position`.

    Args:
        mesh: replaces the board (:func:`board_mesh` surfaces 'cavity_0..8', top on
            z = thickness, underside on z = 0).
        size, thickness, mesh_size, top_mesh_size: of the default board (mm).
        young_modulus, poisson_ratio, density, material: the silicone (kPa, kg/mm^3).
        max_pressure: upper bound of each cavity's pressure (kPa; SofaGym's bound is 40 in its
            units). Actuators: one per cavity, in force mode (pressure), row by row from
            (-x, -y).
        ball_radius, ball_mass, ball_position: the rigid ball (mm, kg), at rest on the top.
        friction: Coulomb coefficient of the ball on the board.
        contact_margin: detection distance (mm).
    """
    ball_radius, ball_mass = p.ball.ball_radius, p.ball.ball_mass
    _require_positive(ball_radius=ball_radius, ball_mass=ball_mass)
    mesh = p.mesh_or(board_mesh, size=size, thickness=thickness, top_mesh_size=top_mesh_size)
    missing = [k for k in range(GRID * GRID) if f"cavity_{k}" not in mesh.surfaces]
    if missing:
        raise ModelError(f"the board mesh has no surface for cavities {missing}")
    body = p.tet_body(mesh, fixed_nodes=fixed_by_box(mesh, mesh.landmarks["fixed_box"]))
    cavities = [
        cavity(mesh, body, f"cavity_{k}", max_pressure=max_pressure) for k in range(GRID * GRID)
    ]
    top = float(mesh.points[:, 2].max())
    x, y = ball_position
    ball = RigidBody(
        Sphere(ball_radius, position=[x, y, top + ball_radius]),
        ball_mass,
        friction=p.contact.friction,
        name="ball",
    )
    # Only the top face meets the ball; the table (z = 0) catches a ball rolled off the board.
    surface = np.unique(mesh.boundary_triangles())
    upper = surface[mesh.points[surface, 2] > top - 1e-6 * thickness]
    table = Plane(point=(0.0, 0.0, 0.0))
    return Model(
        body,
        actuators=cavities,
        contacts=p.contacts([table], points=EmbeddedPoints.at_nodes(upper)),
        rigid_bodies=[ball],
        name="bubble_motion",
    )


def demo_actuation(t: float) -> np.ndarray:
    """Inflate the centre cavity to 30 kPa over 0.5 s: its bubble lifts the middle of the
    board (a ball placed off its top rolls away from it)."""
    values = np.zeros(GRID * GRID)
    values[GRID * GRID // 2] = 30.0 * min(t / 0.5, 1.0)
    return values
