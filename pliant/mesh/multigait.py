"""The Multigait quadruped: a flat H-shaped pneumatic body with five chambers.

Proportions follow the SoftRobots Multigait scene (Shepherd et al., PNAS 2011): a 136 x 58 mm
body 6.3 mm thick, a centre block between four legs, one chamber per leg and one in the
centre. As in the scene's mesh, a chamber is a row of narrow slots across its leg (across the
body in the centre) between a 1 mm floor and a 1.5 mm roof, all at one pressure: inflated, the
slots push the walls between them apart and lengthen the top of the leg, while the floor,
held by the strain-limiting layer (paper in the real robot, a membrane on the underside in
:func:`pliant.robots.multigait.multigait`), keeps its length, so the leg curls towards the
floor. The scene's slots are 0.75 mm wide, ten to a leg; here five 3 mm slots per leg and per
centre keep the mesh coarse. The floor is meshed as a layer of its own:
its top is one flat element boundary, under the slots and the walls alike.

The reference mesh of the SOFA scene (59k tetrahedra) is loaded with
:func:`pliant.mesh.load_mesh`; :func:`reference_cavity_surfaces` finds its chamber walls from
the scene's cavity surfaces.
"""

from __future__ import annotations

from dataclasses import dataclass

import gmsh
import numpy as np

from pliant.errors import MeshError
from pliant.geometry.collision import TriangleMesh
from pliant.mesh.gmsh_session import gmsh_model, mesh_volumes, retry_meshing
from pliant.mesh.shapes import _finish, _require_positive
from pliant.mesh.tetmesh import TetMesh

CHAMBERS = ("centre", "front_left", "front_right", "rear_left", "rear_right")

# A slot: its lower and upper corners.
Slot = tuple[np.ndarray, np.ndarray]


@dataclass(frozen=True)
class MultigaitLayout:
    """The Multigait's dimensions (mm): a `length` x `width` x `thickness` body of a centre
    block `centre_length` long between four legs `leg_width` wide, and its chambers' slots.

    A leg's `leg_slots` slots, `slot` mm long along the leg, are spread evenly from `foot` mm
    behind its tip to `wall` mm before the centre block, between side walls `wall` mm thick.
    The centre's `centre_slots` run across the body between the legs' inner sides, `wall` mm
    from them, spread evenly over the centre block less a `wall` at each end. Slots run from
    a `floor` above the underside to a `roof` below the top.
    """

    length: float = 136.0
    width: float = 58.0
    thickness: float = 6.3
    leg_width: float = 16.0
    centre_length: float = 46.0
    wall: float = 2.0
    floor: float = 1.0
    roof: float = 1.5
    slot: float = 3.0
    leg_slots: int = 5
    centre_slots: int = 5
    foot: float = 5.0

    def __post_init__(self) -> None:
        counts = ("leg_slots", "centre_slots")
        _require_positive(**{k: v for k, v in vars(self).items() if k not in counts})

    def chambers(self) -> dict[str, list[Slot]]:
        """The slots of each chamber, as (lower, upper) corners (front legs at x = 0, left is
        +y)."""
        length, width, wall, slot = self.length, self.width, self.wall, self.slot
        leg_width = self.leg_width
        x0 = (length - self.centre_length) / 2
        z = (self.floor, self.thickness - self.roof)
        y_in, y_out = width / 2 - leg_width + wall, width / 2 - wall
        centre_y = width / 2 - leg_width - wall
        leg_span, centre_span = x0 - self.foot - wall, self.centre_length - 2 * wall
        leg_slots, centre_slots = self.leg_slots, self.centre_slots
        if not (
            y_in < y_out
            and centre_y > 0
            and z[0] < z[1]
            and leg_slots >= 1
            and centre_slots >= 1
            and leg_slots * slot < leg_span
            and centre_slots * slot < centre_span
        ):
            raise MeshError(
                "walls, floor, roof and slots leave no room for the Multigait's chambers"
            )

        def row(start: float, span: float, n: int, ya: float, yb: float) -> list[Slot]:
            pitch = (span - slot) / max(n - 1, 1)
            return [
                (np.array([x, ya, z[0]]), np.array([x + slot, yb, z[1]]))
                for x in start + pitch * np.arange(n)
            ]

        def mirrored(slots: list[Slot], axis: int, plane: float) -> list[Slot]:
            """The same slots reflected through the plane {axis} = `plane`."""
            out = []
            for lower, upper in slots:
                lo, hi = lower.copy(), upper.copy()
                lo[axis], hi[axis] = 2 * plane - upper[axis], 2 * plane - lower[axis]
                out.append((lo, hi))
            return out

        front_left = row(self.foot, leg_span, leg_slots, y_in, y_out)
        rear_left = mirrored(front_left, 0, length / 2)
        return {
            "centre": row(x0 + wall, centre_span, centre_slots, -centre_y, centre_y),
            "front_left": front_left,
            "front_right": mirrored(front_left, 1, 0.0),
            "rear_left": rear_left,
            "rear_right": mirrored(rear_left, 1, 0.0),
        }


def multigait_chambers(**dimensions) -> dict[str, list[Slot]]:
    """The slots of each chamber of the Multigait of `dimensions` (:class:`MultigaitLayout`'s
    fields), as (lower, upper) corners."""
    return MultigaitLayout(**dimensions).chambers()


@retry_meshing
def multigait(*, mesh_size: float = 6.0, **dimensions) -> TetMesh:
    """The Multigait body along +x (front legs at x = 0), width along y (centred), underside
    z = 0; about 8k tetrahedra at the default `mesh_size`. `dimensions`: the fields of
    :class:`MultigaitLayout` (chamber layout: :meth:`MultigaitLayout.chambers`).

    Surfaces: 'cavity_<chamber>' for the chambers of :data:`CHAMBERS` (the walls of all its
    slots), oriented out of the air (positive enclosed volume). The bottom `floor` mm are a
    layer of whole elements. Landmarks: 'centre' (1, 3), the middle of the underside.
    """
    layout = MultigaitLayout(**dimensions)
    _require_positive(mesh_size=mesh_size)
    chambers = layout.chambers()
    length, width, thickness = layout.length, layout.width, layout.thickness
    leg_width, centre_length, floor = layout.leg_width, layout.centre_length, layout.floor
    x0 = (length - centre_length) / 2
    with gmsh_model("multigait"):
        occ = gmsh.model.occ
        parts = [occ.addBox(x0, -width / 2, 0, centre_length, width, thickness)]
        for xa in (0.0, x0 + centre_length):
            for ya in (-width / 2, width / 2 - leg_width):
                parts.append(occ.addBox(xa, ya, 0, x0, leg_width, thickness))
        fused, _ = occ.fuse([(3, parts[0])], [(3, p) for p in parts[1:]])
        holes = [
            (3, occ.addBox(*lo, *(hi - lo))) for slots in chambers.values() for lo, hi in slots
        ]
        body, _ = occ.cut(fused, holes)
        # The floor as a volume of its own: its top is an element boundary everywhere.
        below = occ.addBox(-1.0, -width, -1.0, length + 2.0, 2 * width, floor + 1.0)
        floor_part, _ = occ.intersect(occ.copy(body), [(3, below)], removeTool=False)
        upper_part, _ = occ.cut(body, [(3, below)])
        occ.fragment(floor_part, upper_part)
        occ.removeAllDuplicates()
        points, tets = mesh_volumes(mesh_size)
    surfaces = _chamber_walls(points, tets, chambers, tolerance=1e-6 * length)
    landmarks = {"centre": [length / 2, 0.0, 0.5 * floor]}
    return _finish(points, tets, landmarks, surfaces)


def _chamber_walls(
    points: np.ndarray, tets: np.ndarray, chambers: dict[str, list[Slot]], tolerance: float
) -> dict[str, np.ndarray]:
    """Boundary triangles on the slot walls of each chamber, oriented out of the air.

    The body's boundary triangles have outward normals, which on a cavity wall point into the
    air; flipping them makes the normals point into the material.
    """
    boundary = TetMesh(points=points, tets=tets).boundary_triangles()
    centres = points[boundary].mean(axis=1)
    surfaces = {}
    for name, slots in chambers.items():
        on_wall = np.zeros(len(boundary), dtype=bool)
        for lower, upper in slots:
            on_wall |= np.all(
                (centres >= lower - tolerance) & (centres <= upper + tolerance), axis=1
            )
        if not on_wall.any():
            raise MeshError(f"the {name} chamber of the Multigait has no wall triangles")
        surfaces[f"cavity_{name}"] = boundary[on_wall][:, [0, 2, 1]]
    return surfaces


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
