"""Parametric soft-robot bodies, meshed with linear tetrahedra. Lengths in millimetres.

Each builder returns a validated `TetMesh` whose `landmarks` name the points a robot model needs
(cable paths, pull points, effectors, the box of fixed nodes) and, for pneumatic bodies, whose
`surfaces` hold the cavity walls. Every landmark that the model embeds in the material (cable
points, effectors, contact points) is checked to lie in the mesh.

Geometry is built with gmsh's OpenCASCADE kernel, except the structured `box_beam`. The same
parameters always give the same mesh.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Literal

import gmsh
import numpy as np

from pliant.errors import MeshError, ModelError
from pliant.mesh.gmsh_session import gmsh_model, mesh_volumes, retry_meshing
from pliant.mesh.locate import locate_points
from pliant.mesh.quality import validate_mesh
from pliant.mesh.tetmesh import TetMesh

FingerResolution = Literal["coarse", "fine", "superfine"]

# Mesh sizes that reproduce the thesis' three Soft Finger meshes (1557, 8895, 17852 tetrahedra,
# Fig. 5.5) at the default dimensions.
FINGER_MESH_SIZES: dict[str, float] = {"coarse": 11.0, "fine": 3.75, "superfine": 2.67}

# Landmarks that are embedded in the material rather than fixed in space.
_EMBEDDED_PREFIXES = ("cable_points", "effector", "contact_points", "tip", "neutral_fibre")


def _require_positive(**values: float) -> None:
    for name, value in values.items():
        if not (math.isfinite(value) and value > 0):
            raise ModelError(f"{name} must be a positive finite number, got {value!r}")


def _require_whole(name: str, value: float, minimum: int = 1) -> None:
    if int(value) != value or value < minimum:
        kind = "a positive integer" if minimum == 1 else f"an integer >= {minimum}"
        raise ModelError(f"{name} must be {kind}, got {value!r}")


def require_arguments(arguments: Mapping[str, float], positive: str = "", **whole: int) -> None:
    """ModelError unless the `arguments` named in `positive` (separated by spaces) are positive
    finite numbers and each one named in `whole` a whole number of at least its value.
    A builder's first statement ``require_arguments(locals(), "length width", n=1)`` checks
    its own arguments."""
    _require_positive(**{name: arguments[name] for name in positive.split()})
    for name, minimum in whole.items():
        _require_whole(name, arguments[name], minimum)


def _box(lower: np.ndarray | list[float], upper: np.ndarray | list[float]) -> np.ndarray:
    return np.array([lower, upper], dtype=np.float64)


def _finish(
    points: np.ndarray,
    tets: np.ndarray,
    landmarks: dict[str, np.ndarray],
    surfaces: dict[str, np.ndarray] | None = None,
) -> TetMesh:
    """Validate the mesh and check that every embedded landmark lies in its material."""
    validate_mesh(points, tets)
    mesh = TetMesh(
        points=points,
        tets=tets,
        surfaces=surfaces or {},
        landmarks={k: np.atleast_2d(np.asarray(v, dtype=np.float64)) for k, v in landmarks.items()},
    )
    # Landmarks on flat boundary faces (tips, contact points) are inside up to round-off.
    tolerance = 1e-6 * float(np.linalg.norm(np.ptp(points, axis=0)))
    for name, value in mesh.landmarks.items():
        if name.startswith(_EMBEDDED_PREFIXES):
            try:
                locate_points(mesh, value, tolerance=tolerance)
            except ModelError as exc:
                raise MeshError(
                    f"landmark {name!r} is not inside the material: {exc}. A mesh too coarse for"
                    " the geometry cuts its curved surfaces inside it (facets sag by about"
                    " size^2 / 8 r on a radius r): lower mesh_size"
                ) from exc
    return mesh


def box_beam(
    length: float = 100.0,
    width: float = 20.0,
    height: float = 20.0,
    nx: int = 10,
    ny: int = 2,
    nz: int = 2,
    origin: tuple[float, float, float] = (0.0, 0.0, 0.0),
) -> TetMesh:
    """A structured beam along +x: nx x ny x nz hexahedra, each split into 6 tetrahedra.

    The split is Kuhn's (Freudenthal's): every cube is cut along its (0,0,0)-(1,1,1) diagonal
    into the 6 tetrahedra of the monotone paths between these corners, the same way in every
    cell, so that the faces of neighbouring cells conform. These are the meshes of SOFA's
    cantilever benchmarks (10x2x2 -> 240 tetrahedra, 20x4x4 -> 1920, 40x8x8 -> 15360).

    Landmarks: 'fixed_box' around the x = origin face, 'tip' at the centre of the far face.
    """
    require_arguments(locals(), "length width height", nx=1, ny=1, nz=1)
    nx, ny, nz = int(nx), int(ny), int(nz)
    x0 = np.asarray(origin, dtype=np.float64)
    axes = [np.linspace(0.0, size, n + 1) for size, n in ((length, nx), (width, ny), (height, nz))]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    points = grid + x0

    def node(i: np.ndarray, j: np.ndarray, k: np.ndarray) -> np.ndarray:
        return (i * (ny + 1) + j) * (nz + 1) + k

    i, j, k = (
        a.ravel() for a in np.meshgrid(np.arange(nx), np.arange(ny), np.arange(nz), indexing="ij")
    )
    tets = []
    for order in itertools.permutations(range(3)):
        corner = np.zeros(3, dtype=np.int64)
        path = [corner.copy()]
        for axis in order:
            corner[axis] += 1
            path.append(corner.copy())
        tet = np.stack([node(i + c[0], j + c[1], k + c[2]) for c in path], axis=1)
        # An odd permutation of the axes walks the cube with negative orientation.
        if np.linalg.det(np.eye(3)[list(order)]) < 0:
            tet = tet[:, [0, 2, 1, 3]]
        tets.append(tet)
    tets = np.concatenate(tets).astype(np.int64)

    tol = 1e-3 * min(length / nx, width / ny, height / nz)
    landmarks = {
        "fixed_box": _box(x0 - tol, x0 + [tol, width + tol, height + tol]),
        "tip": x0 + [length, width / 2, height / 2],
    }
    return _finish(points, tets, landmarks)


def _prism_in_radial_plane(outline_rz: np.ndarray, width: float, angle: float) -> int:
    """Extrude an outline drawn in the (r, z) half-plane at azimuth `angle` by `width`.

    The outline is a closed polygon; the solid spans +-width/2 about the half-plane.
    """
    occ = gmsh.model.occ
    radial = np.array([math.cos(angle), math.sin(angle), 0.0])
    tangent = np.array([-math.sin(angle), math.cos(angle), 0.0])
    corners = [
        r * radial + z * np.array([0.0, 0.0, 1.0]) - width / 2 * tangent for r, z in outline_rz
    ]
    tags = [occ.addPoint(*c) for c in corners]
    lines = [occ.addLine(tags[n], tags[(n + 1) % len(tags)]) for n in range(len(tags))]
    face = occ.addPlaneSurface([occ.addCurveLoop(lines)])
    out = occ.extrude([(2, face)], *(width * tangent))
    return next(tag for dim, tag in out if dim == 3)


def _bar_outline(a: np.ndarray, b: np.ndarray, thickness: float) -> np.ndarray:
    """Rectangle of the given thickness around the segment a-b in the (r, z) plane."""
    d = (b - a) / np.linalg.norm(b - a)
    n = np.array([-d[1], d[0]]) * thickness / 2
    return np.array([a - n, b - n, b + n, a + n])


def _fuse_all(volumes: list[int]) -> None:
    occ = gmsh.model.occ
    if len(volumes) > 1:
        occ.fuse([(3, volumes[0])], [(3, v) for v in volumes[1:]])
    occ.removeAllDuplicates()


@retry_meshing
def diamond(
    *,
    elbow_radius: float = 97.0,
    elbow_height: float = 45.0,
    effector_height: float = 125.0,
    leg_width: float = 20.0,
    leg_thickness: float = 16.0,
    base_radius: float = 65.0,
    base_width: float = 30.0,
    base_bottom: float = -37.0,
    base_top: float = -10.0,
    mesh_size: float = 13.0,
) -> TetMesh:
    """Pliant's Diamond parallel robot: a cross-shaped base, four legs, a top effector hub.

    Each leg rises from an arm of the base to an elbow at (elbow_radius, elbow_height) in its
    vertical half-plane (azimuths 90, 180, 270, 0 degrees: +y, -x, -y, +x), then converges to
    the hub carrying the effector on the z axis. The default dimensions follow the SoftRobots
    Diamond in the frame of its SOFA scene (mesh rotated 90 degrees about x and raised 35 mm):
    effector (0, 0, 125), cable attachments at the elbows (0, +-97, 45), (+-97, 0, 45), pull
    points (0, +-10, 30), (+-10, 0, 30), base fixed by the box [-15, 15]^2 x [-40, 10].

    Args:
        elbow_radius, elbow_height: position of the elbows, where the cables are attached.
        effector_height: height of the effector point on the z axis.
        leg_width: leg size across its vertical half-plane.
        leg_thickness: leg size within its half-plane, across the leg.
        base_radius, base_width: half-length and width of the two bars forming the base cross.
        base_bottom, base_top: heights of the base's faces.
        mesh_size: largest element edge.

    Landmarks: 'effector' (1, 3); 'cable_points_0..3' (1, 3) at the elbows, in the order +y,
    -x, -y, +x; 'pull_points_0..3' (1, 3) under the hub at z = 30, 10 mm off the axis, in the
    same order; 'fixed_box' (2, 3).
    """
    require_arguments(
        locals(), "elbow_radius leg_width leg_thickness base_radius base_width mesh_size"
    )
    if not base_bottom < base_top < elbow_height < effector_height:
        raise ModelError(
            "the diamond needs base_bottom < base_top < elbow_height < effector_height, got "
            f"{base_bottom}, {base_top}, {elbow_height}, {effector_height}"
        )
    if not (leg_width < base_width and elbow_radius - leg_thickness > base_radius / 2):
        raise ModelError("legs must be narrower than the base and the elbows outside the base")

    base_mid = (base_bottom + base_top) / 2
    foot = np.array([base_radius - leg_thickness, base_mid])
    elbow = np.array([elbow_radius, elbow_height])
    hub_top = effector_height + 2.0
    top = np.array([0.0, hub_top - leg_thickness])
    # The inner faces of the four upper bars meet on the axis; the hub must reach well below,
    # or the boolean union leaves a sliver of tiny faces there.
    d = (top - elbow) / np.linalg.norm(top - elbow)
    inner = top + np.array([-d[1], d[0]]) * leg_thickness / 2
    hub_bottom = inner[1] - inner[0] * d[1] / d[0] - leg_thickness / 2
    # A knob slightly thicker than the bars: their corners cut its surface instead of touching.
    knob_radius = 0.6 * leg_thickness
    angles = [math.pi / 2 * (1 + n) for n in range(4)]  # +y, -x, -y, +x

    with gmsh_model("diamond"):
        occ = gmsh.model.occ
        volumes = [
            occ.addBox(
                -base_radius,
                -base_width / 2,
                base_bottom,
                2 * base_radius,
                base_width,
                base_top - base_bottom,
            ),
            occ.addBox(
                -base_width / 2,
                -base_radius,
                base_bottom,
                base_width,
                2 * base_radius,
                base_top - base_bottom,
            ),
            occ.addCylinder(0, 0, hub_bottom, 0, 0, hub_top - hub_bottom, 0.75 * leg_width),
        ]
        for angle in angles:
            for a, b in ((foot, elbow), (elbow, top)):
                volumes.append(
                    _prism_in_radial_plane(_bar_outline(a, b, leg_thickness), leg_width, angle)
                )
            radial = np.array([math.cos(angle), math.sin(angle), 0.0])
            tangent = np.array([-math.sin(angle), math.cos(angle), 0.0])
            start = elbow[0] * radial + [0, 0, elbow[1]] - leg_width / 2 * tangent
            volumes.append(occ.addCylinder(*start, *(leg_width * tangent), knob_radius))
        _fuse_all(volumes)
        points, tets = mesh_volumes(mesh_size)

    landmarks: dict[str, np.ndarray] = {"effector": [0.0, 0.0, effector_height]}
    for n, angle in enumerate(angles):
        radial = np.array([math.cos(angle), math.sin(angle), 0.0])
        landmarks[f"cable_points_{n}"] = elbow_radius * radial + [0, 0, elbow_height]
        landmarks[f"pull_points_{n}"] = 10.0 * radial + [0, 0, 30.0]
    landmarks["fixed_box"] = _box([-15.0, -15.0, base_bottom - 3.0], [15.0, 15.0, base_top + 20.0])
    return _finish(points, tets, landmarks)


@retry_meshing
def soft_finger(
    *,
    length: float = 40.0,
    height: float = 20.0,
    joint_height: float = 6.0,
    width: float = 20.0,
    joint_length: float = 12.0,
    n_folds: int = 2,
    fold_thickness: float = 2.0,
    cable_offset: float | None = None,
    resolution: FingerResolution = "coarse",
    mesh_size: float | None = None,
) -> TetMesh:
    """The parametric Soft Finger: three phalanges joined by two accordion joints, two cables.

    The finger lies along +x from its base at x = 0, with its width along y (centred) and its
    height along z from the underside z = 0. A joint is a bar of height `joint_height` centred
    in the finger's height, carrying `n_folds` thin folds of 80 % of the finger's height: the
    notches between them make the joint bend like an accordion. The design parameters of the
    thesis are `length` (one phalanx, 38-42 mm), `height` (20-22 mm) and `joint_height`
    (5-8 mm), Section 5.1.6.

    Two cables run along the finger, `cable_offset` below (cable 0, closes the finger towards
    -z) and above (cable 1) the mid-height, held in each phalanx near both of its faces and
    crossing the joints freely (in a channel), as tendons do: their lever arm about the joint
    bars is the offset itself, so that a pull bends the joints rather than compressing them.

    Args:
        length, height, width: size of one phalanx.
        joint_height, joint_length: size of the bar that forms each joint.
        n_folds, fold_thickness: folds of each accordion joint.
        cable_offset: distance of the cables from the mid-height, 0.4 * height by default
            (less than half the height less 1 mm).
        resolution: 'coarse', 'fine' or 'superfine', giving about 1.5k, 9k and 18k tetrahedra
            at the default dimensions, like the thesis' three meshes.
        mesh_size: largest element edge; overrides `resolution`.

    Landmarks: 'cable_points_0/1' (6, 3) 1 mm inside both end faces of every phalanx (the
    last one 1 mm before the fingertip); 'pull_points_0/1' (1, 3) where the cables leave the
    base face;
    'effector' (1, 3) 1 mm inside the fingertip face; 'contact_points' (3, 3) on the underside
    of the last phalanx; 'fixed_box' (2, 3) around the base face.
    """
    require_arguments(locals(), "length height joint_height width joint_length fold_thickness")
    if mesh_size is None:
        if resolution not in FINGER_MESH_SIZES:
            raise ModelError(
                f"resolution must be one of {sorted(FINGER_MESH_SIZES)}, got {resolution!r}"
            )
        mesh_size = FINGER_MESH_SIZES[resolution]
    if cable_offset is None:
        cable_offset = 0.4 * height
    _require_positive(cable_offset=cable_offset, mesh_size=mesh_size)
    if not joint_height < 0.8 * height:
        raise ModelError(f"joint_height {joint_height} must be below 80 % of height {height}")
    if not cable_offset < height / 2 - 1.0:
        raise ModelError(f"cable_offset {cable_offset} must lie 1 mm inside height / 2")
    if int(n_folds) != n_folds or n_folds < 0 or n_folds * fold_thickness >= joint_length:
        raise ModelError(f"{n_folds} folds of {fold_thickness} mm do not fit in the joint")

    pitch = length + joint_length
    total = 3 * length + 2 * joint_length
    mid = height / 2
    fold_height = 0.8 * height
    gap = (joint_length - n_folds * fold_thickness) / (n_folds + 1)

    with gmsh_model("soft_finger"):
        occ = gmsh.model.occ
        volumes = [occ.addBox(n * pitch, -width / 2, 0, length, width, height) for n in range(3)]
        for n in range(2):
            x0 = n * pitch + length
            volumes.append(
                occ.addBox(
                    x0, -width / 2, mid - joint_height / 2, joint_length, width, joint_height
                )
            )
            for f in range(n_folds):
                xf = x0 + gap + f * (fold_thickness + gap)
                volumes.append(
                    occ.addBox(
                        xf, -width / 2, mid - fold_height / 2, fold_thickness, width, fold_height
                    )
                )
        _fuse_all(volumes)
        points, tets = mesh_volumes(mesh_size)

    x_path = (np.arange(3)[:, None] * pitch + np.array([1.0, length - 1.0])).ravel()
    landmarks: dict[str, np.ndarray] = {}
    for n, z in enumerate((mid - cable_offset, mid + cable_offset)):
        landmarks[f"cable_points_{n}"] = np.column_stack(
            [x_path, np.zeros_like(x_path), np.full_like(x_path, z)]
        )
        landmarks[f"pull_points_{n}"] = [0.0, 0.0, z]
    landmarks["effector"] = [total - 1.0, 0.0, mid]
    x_contact = 2 * pitch + length * np.array([0.25, 0.5, 0.75])
    landmarks["contact_points"] = np.column_stack([x_contact, np.zeros(3), np.zeros(3)])
    margin = 1.0
    landmarks["fixed_box"] = _box(
        [-margin, -width / 2 - margin, -margin], [margin, width / 2 + margin, height + margin]
    )
    return _finish(points, tets, landmarks)


@retry_meshing
def trunk(
    *,
    length: float = 195.0,
    base_radius: float = 13.0,
    tip_radius: float = 5.0,
    cable_inset: float = 3.0,
    cable_spacing: float = 17.5,
    first_cable_point: float = 21.0,
    fixed_length: float = 20.0,
    mesh_size: float = 5.2,
) -> TetMesh:
    """The cable-driven Trunk: a tapered solid cylinder along +z from z = 0, eight cables.

    Defaults follow the SoftRobots / SofaGym Trunk: 195 mm long, radius 13 mm at the base and
    5 mm at the tip, cable points every 17.5 mm along z from z = 21 mm, base fixed over its
    first 20 mm (box [-20, 20]^2 x [0, 20]).

    The cables run `cable_inset` inside the surface, parallel to it, at azimuths +y, -x, -y,
    +x: cables 0-3 over the full length, cables 4-7 (same azimuths) over half of it, as in the
    reference, whose long and short cables share their paths up to the short ones' end.

    Landmarks: 'cable_points_0..7' (k, 3); 'pull_points_0..7' (1, 3) on the base plane at
    radius 10 mm, like the reference (0, +-10, 0), (+-10, 0, 0); 'fixed_box' (2, 3);
    'effector' (1, 3) at the tip centre; 'neutral_fibre' (21, 3) along the axis.
    """
    require_arguments(
        locals(),
        "length base_radius tip_radius cable_inset cable_spacing first_cable_point fixed_length"
        " mesh_size",
    )
    if not cable_inset < min(base_radius, tip_radius):
        raise ModelError(f"cable_inset {cable_inset} must be less than both radii")
    if not first_cable_point < length:
        raise ModelError(f"first_cable_point {first_cable_point} must lie below the tip")

    with gmsh_model("trunk"):
        gmsh.model.occ.addCone(0, 0, 0, 0, 0, length, base_radius, tip_radius)
        points, tets = mesh_volumes(mesh_size)

    z_long = np.arange(first_cable_point, length, cable_spacing)
    z_short = z_long[z_long <= length / 2]
    landmarks: dict[str, np.ndarray] = {}
    for n in range(8):
        angle = math.pi / 2 * (1 + n % 4)  # +y, -x, -y, +x
        radial = np.array([math.cos(angle), math.sin(angle), 0.0])
        z = z_long if n < 4 else z_short
        r = base_radius + (tip_radius - base_radius) * z / length - cable_inset
        landmarks[f"cable_points_{n}"] = r[:, None] * radial + z[:, None] * [0, 0, 1.0]
        landmarks[f"pull_points_{n}"] = 10.0 * radial
    half = base_radius + 7.0
    landmarks["fixed_box"] = _box([-half, -half, 0.0], [half, half, fixed_length])
    landmarks["effector"] = [0.0, 0.0, length]
    landmarks["neutral_fibre"] = np.column_stack(
        [np.zeros(21), np.zeros(21), np.linspace(0.0, length, 21)]
    )
    return _finish(points, tets, landmarks)


@dataclass(frozen=True)
class PneuNetLayout:
    """A PneuNet's dimensions (mm): a `length` x `width` base layer `base_height` thick under
    `n_chambers` blocks `chamber_height` tall, separated by slits `gap` wide, each holding a
    closed box-shaped cavity with walls `wall` thick and its floor `floor` above the
    underside. ModelError unless they are positive and leave room for the chambers."""

    length: float = 115.0
    width: float = 20.0
    base_height: float = 8.0
    chamber_height: float = 20.0
    n_chambers: int = 6
    gap: float = 4.0
    wall: float = 2.5
    floor: float = 4.0

    @property
    def block(self) -> float:
        """Length of a chamber's block along the finger."""
        return (self.length - (self.n_chambers - 1) * self.gap) / self.n_chambers

    @property
    def height(self) -> float:
        return self.base_height + self.chamber_height

    def __post_init__(self) -> None:
        _require_positive(**{k: v for k, v in vars(self).items() if k != "n_chambers"})
        _require_whole("n_chambers", self.n_chambers)
        block, width, wall, floor = self.block, self.width, self.wall, self.floor
        if not (
            block > 2 * wall
            and width > 2 * wall
            and floor < self.base_height
            and floor < self.height - wall
        ):
            raise ModelError(
                f"walls of {wall} mm and a floor at {floor} mm leave no room for"
                f" {self.n_chambers} chambers in a {self.length} x {width} x {self.height} mm"
                " finger"
            )

    def cavity_boxes(self) -> list[tuple[np.ndarray, np.ndarray]]:
        """Lower and upper corners of each chamber; the total cavity volume is the sum over
        chambers of prod(upper - lower)."""
        half, wall, pitch = self.width / 2, self.wall, self.block + self.gap
        return [
            (
                np.array([n * pitch + wall, -half + wall, self.floor]),
                np.array([n * pitch + self.block - wall, half - wall, self.height - wall]),
            )
            for n in range(self.n_chambers)
        ]


@retry_meshing
def pneunet(*, mesh_size: float = 6.0, **dimensions) -> TetMesh:
    """A PneuNet bending actuator: a strain-limiting base under a row of sealed chambers;
    `dimensions`: the fields of :class:`PneuNetLayout`.

    The finger lies along +x from its fixed end at x = 0, width along y (centred), height along
    z from the underside z = 0. On top of a solid base layer of `base_height` stand
    `n_chambers` blocks separated by slits of width `gap`; each block holds a closed box-shaped
    cavity whose walls are `wall` thick and whose floor sits `floor` above the underside.
    Inflated together (one cavity) or one by one, the chambers expand against each other and
    bend the finger towards the base layer. Proportions follow the SoftRobots PneuNet.

    Surfaces: 'cavity_0..' the walls of each chamber and 'cavity' all of them, triangles of the
    volume mesh oriented out of the enclosed air into the material, so that the enclosed volume
    sum x0 . (x1 x x2) / 6 is positive and equals `cavity_volume`.

    Landmarks: 'effector' (1, 3) 1 mm inside the tip, in the base layer; 'fixed_box' (2, 3)
    around the x = 0 face.
    """
    layout = PneuNetLayout(**dimensions)
    _require_positive(mesh_size=mesh_size)
    cavities = layout.cavity_boxes()
    length, width, base_height = layout.length, layout.width, layout.base_height
    block, gap, height = layout.block, layout.gap, layout.height

    with gmsh_model("pneunet"):
        occ = gmsh.model.occ
        body = [occ.addBox(0, -width / 2, 0, length, width, base_height)]
        body += [
            occ.addBox(
                n * (block + gap),
                -width / 2,
                base_height - 1.0,
                block,
                width,
                layout.chamber_height + 1.0,
            )
            for n in range(layout.n_chambers)
        ]
        points, tets, surfaces = _hollowed(body, cavities, mesh_size, 1e-6 * length)
    landmarks = {
        "effector": [length - 1.0, 0.0, base_height / 2],
        "fixed_box": _box([-1.0, -width / 2 - 1.0, -1.0], [1.0, width / 2 + 1.0, height + 1.0]),
    }
    return _finish(points, tets, landmarks, surfaces)


def pneunet_cavity_boxes(**dimensions) -> list[tuple[np.ndarray, np.ndarray]]:
    """Lower and upper corners of each chamber of `pneunet` with the same `dimensions`
    (:meth:`PneuNetLayout.cavity_boxes`)."""
    return PneuNetLayout(**dimensions).cavity_boxes()


def _hollowed(
    parts: list[int], cavities: list[tuple[np.ndarray, np.ndarray]], mesh_size: float, tolerance
) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
    """The union of the volumes `parts` of the open gmsh model, less the boxes `cavities`,
    meshed: points, tetrahedra and the cavities' walls (:func:`_cavity_surfaces`)."""
    occ = gmsh.model.occ
    fused, _ = occ.fuse([(3, parts[0])], [(3, v) for v in parts[1:]])
    holes = [(3, occ.addBox(*lo, *(hi - lo))) for lo, hi in cavities]
    occ.cut(fused, holes)
    occ.removeAllDuplicates()
    points, tets = mesh_volumes(mesh_size)
    return points, tets, _cavity_surfaces(points, tets, cavities, tolerance=tolerance)


def _cavity_surfaces(
    points: np.ndarray,
    tets: np.ndarray,
    cavities: list[tuple[np.ndarray, np.ndarray]],
    tolerance: float,
) -> dict[str, np.ndarray]:
    """Boundary triangles on the walls of each box-shaped cavity, oriented out of the air.

    The body's boundary triangles have outward normals, which on a cavity wall point into the
    air; flipping them makes the normals point into the material.
    """
    boundary = TetMesh(points=points, tets=tets).boundary_triangles()
    centres = points[boundary].mean(axis=1)
    surfaces: dict[str, np.ndarray] = {}
    for n, (lower, upper) in enumerate(cavities):
        on_wall = np.all((centres >= lower - tolerance) & (centres <= upper + tolerance), axis=1)
        if not on_wall.any():
            raise MeshError(f"chamber {n} of the PneuNet has no wall triangles")
        surfaces[f"cavity_{n}"] = boundary[on_wall][:, [0, 2, 1]]
    surfaces["cavity"] = np.concatenate([surfaces[f"cavity_{n}"] for n in range(len(cavities))])
    return surfaces


@retry_meshing
def stiff_flop(
    *,
    module_length: float = 50.0,
    radius: float = 15.0,
    n_modules: int = 2,
    chamber_radius: float = 2.5,
    chamber_offset: float = 8.0,
    pair_spacing: float = 7.0,
    cap: float = 3.0,
    mesh_size: float = 8.0,
) -> TetMesh:
    """The Stiff-Flop (Cianchetti et al. 2014): a silicone cylinder along +z from z = 0 of
    `n_modules` modules, each with three pairs of cylindrical chambers.

    Pair j of module i sits at azimuth 2 pi j / 3 (+x first), its two chambers `pair_spacing`
    apart across that azimuth, at `chamber_offset` from the axis; each chamber is closed by
    `cap` of material at both ends of its module. The chambers' walls are meshed with five
    elements round (their meshed volume below the cylinder's), the body with `mesh_size`.

    Surfaces: 'cavity_{i}_{j}' the walls of pair j of module i (both chambers, oriented out of
    the air into the material).
    Landmarks: 'chamber_axes_{i}_{j}' (2, 2) the xy centres of the pair's two chambers;
    'effector_tip' and 'effector_middle' (1, 3) on the axis at the tip and between the
    modules; 'fixed_box' (2, 3) around the base face z = 0.
    """
    require_arguments(
        locals(),
        "module_length radius chamber_radius chamber_offset pair_spacing cap mesh_size",
        n_modules=1,
    )
    reach = math.hypot(chamber_offset, pair_spacing / 2) + chamber_radius
    if not (reach < radius - 1.0 and pair_spacing > 2 * chamber_radius + 1.0):
        raise ModelError(
            f"chambers of radius {chamber_radius} mm at {chamber_offset} mm, {pair_spacing} mm"
            f" apart, do not fit with walls of 1 mm in a cylinder of radius {radius} mm"
        )
    if not 2 * cap < module_length:
        raise ModelError(f"caps of {cap} mm leave no chamber in a {module_length} mm module")
    length = n_modules * module_length
    centres: dict[tuple[int, int], np.ndarray] = {}
    for j in range(3):
        a = 2 * math.pi * j / 3
        radial = np.array([math.cos(a), math.sin(a)])
        tangent = np.array([-radial[1], radial[0]])
        centres[j] = np.array(
            [chamber_offset * radial + s * pair_spacing / 2 * tangent for s in (-1, 1)]
        )
    with gmsh_model("stiff_flop"):
        occ = gmsh.model.occ
        body = occ.addCylinder(0, 0, 0, 0, 0, length, radius)
        holes = [
            (
                3,
                occ.addCylinder(
                    *c, i * module_length + cap, 0, 0, module_length - 2 * cap, chamber_radius
                ),
            )
            for i in range(n_modules)
            for j in range(3)
            for c in centres[j]
        ]
        occ.cut([(3, body)], holes)
        occ.removeAllDuplicates()
        occ.synchronize()
        # Five elements round each chamber, whatever the body's size: coarser, a chamber's
        # section collapses (its wall pinched onto a chord shared by four faces).
        chamber_size = min(mesh_size, 2 * math.pi * chamber_radius / 5)
        for dim, tag in gmsh.model.getEntities(0):
            x, y, _ = gmsh.model.getValue(dim, tag, [])
            if math.hypot(x, y) < radius - 0.5:
                gmsh.model.mesh.setSize([(dim, tag)], chamber_size)
        points, tets = mesh_volumes(mesh_size)
    boundary = TetMesh(points=points, tets=tets).boundary_triangles()
    corners = points[boundary]  # (t, 3, 3): a wall triangle has its three corners on the wall
    tol = 1e-6 * length
    surfaces: dict[str, np.ndarray] = {}
    landmarks: dict[str, np.ndarray] = {}
    for i in range(n_modules):
        z0, z1 = i * module_length + cap - tol, (i + 1) * module_length - cap + tol
        in_module = np.all((corners[..., 2] > z0) & (corners[..., 2] < z1), axis=1)
        for j in range(3):
            near = np.zeros(len(boundary), dtype=bool)
            for c in centres[j]:
                gap = np.linalg.norm(corners[..., :2] - c, axis=2)
                near |= np.all(gap < chamber_radius + tol, axis=1)
            walls = boundary[in_module & near]
            if len(walls) < 8:
                raise MeshError(f"chamber pair {j} of module {i} has no walls: lower mesh_size")
            # Boundary normals point into the air on a cavity wall: flip them.
            surfaces[f"cavity_{i}_{j}"] = walls[:, [0, 2, 1]]
            landmarks[f"chamber_axes_{i}_{j}"] = centres[j]
    landmarks["effector_tip"] = [0.0, 0.0, length]
    landmarks["effector_middle"] = [0.0, 0.0, length / 2]
    landmarks["fixed_box"] = _box([-radius - 1, -radius - 1, -1.0], [radius + 1, radius + 1, 1e-3])
    return _finish(points, tets, landmarks, surfaces)
