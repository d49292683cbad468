"""Tests of pliant.mesh: builders, quality checks, file I/O and point location."""

from __future__ import annotations

from pathlib import Path

import gmsh
import meshio
import numpy as np
import pytest

from pliant.errors import (
    DegenerateElementError,
    DisconnectedMeshError,
    InvertedElementError,
    MeshError,
    MeshFileError,
    MeshingError,
    ModelError,
)
from pliant.mesh import (
    TetMesh,
    box_beam,
    diamond,
    fix_orientation,
    gmsh_session,
    load_mesh,
    locate_points,
    pneunet,
    remove_unused_nodes,
    save_mesh,
    soft_finger,
    trunk,
    validate_mesh,
)
from pliant.mesh.shapes import pneunet_cavity_boxes

REFERENCE_MESHES = Path(__file__).resolve().parents[3] / "shared" / "meshes"

# A single positively oriented tetrahedron.
UNIT_TET_POINTS = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
UNIT_TET = np.array([[0, 1, 2, 3]])


def enclosed_volume(points: np.ndarray, triangles: np.ndarray) -> float:
    """Volume enclosed by a closed triangulated surface: sum of x0 . (x1 x x2) / 6."""
    p = points[triangles]
    return float(np.einsum("ij,ij->i", p[:, 0], np.cross(p[:, 1], p[:, 2])).sum() / 6.0)


def in_box(points: np.ndarray, box: np.ndarray) -> np.ndarray:
    return np.all((points >= box[0]) & (points <= box[1]), axis=1)


# ---------------------------------------------------------------------------------------------
# Structured beam


@pytest.mark.parametrize(
    ("n", "expected"), [((10, 2, 2), 240), ((20, 4, 4), 1920), ((3, 1, 2), 36)]
)
def test_box_beam_counts_and_volume_are_exact(n: tuple[int, int, int], expected: int) -> None:
    nx, ny, nz = n
    mesh = box_beam(100.0, 20.0, 30.0, nx, ny, nz, origin=(1.0, -2.0, 3.0))
    assert mesh.n_tets == expected == 6 * nx * ny * nz
    assert mesh.n_nodes == (nx + 1) * (ny + 1) * (nz + 1)
    volumes = mesh.signed_volumes()
    assert volumes.min() > 0
    # Each cell is split into 6 tetrahedra of equal volume dx dy dz / 6.
    np.testing.assert_allclose(volumes, 100 * 20 * 30 / (6 * nx * ny * nz), rtol=1e-12)
    np.testing.assert_allclose(volumes.sum(), 100.0 * 20.0 * 30.0, rtol=1e-12)


def test_box_beam_faces_conform() -> None:
    nx, ny, nz = 4, 3, 2
    mesh = box_beam(nx=nx, ny=ny, nz=nz)
    # Conforming cells leave only the outer quads, each split in two, on the boundary.
    assert len(mesh.boundary_triangles()) == 2 * 2 * (nx * ny + ny * nz + nx * nz)


def test_box_beam_landmarks() -> None:
    mesh = box_beam(length=100, width=20, height=10, nx=10, ny=2, nz=2, origin=(5, 0, 0))
    fixed = in_box(mesh.points, mesh.landmarks["fixed_box"])
    np.testing.assert_array_equal(fixed, np.isclose(mesh.points[:, 0], 5.0))
    assert fixed.sum() == 3 * 3
    np.testing.assert_allclose(mesh.landmarks["tip"], [[105.0, 10.0, 5.0]])


def test_box_beam_rejects_bad_parameters() -> None:
    with pytest.raises(ModelError, match="nx"):
        box_beam(nx=0)
    with pytest.raises(ModelError, match="length"):
        box_beam(length=-1.0)


# ---------------------------------------------------------------------------------------------
# gmsh builders


@pytest.fixture(scope="module")
def built() -> dict[str, TetMesh]:
    return {
        "diamond": diamond(),
        "soft_finger": soft_finger(resolution="coarse"),
        "trunk": trunk(),
        "pneunet": pneunet(),
    }


TET_RANGES = {
    "diamond": (3000, 5000),
    "soft_finger": (1000, 2200),
    "trunk": (1500, 3000),
    "pneunet": (2000, 4500),
}

EXPECTED_LANDMARKS = {
    "diamond": ["effector", "fixed_box"]
    + [f"{kind}_{n}" for kind in ("cable_points", "pull_points") for n in range(4)],
    "soft_finger": ["effector", "fixed_box", "contact_points"]
    + [f"{kind}_{n}" for kind in ("cable_points", "pull_points") for n in range(2)],
    "trunk": ["effector", "fixed_box", "neutral_fibre"]
    + [f"{kind}_{n}" for kind in ("cable_points", "pull_points") for n in range(8)],
    "pneunet": ["effector", "fixed_box"],
}


@pytest.mark.parametrize("name", sorted(TET_RANGES))
def test_builder_gives_a_valid_mesh_of_the_expected_size(
    built: dict[str, TetMesh], name: str
) -> None:
    mesh = built[name]
    low, high = TET_RANGES[name]
    assert low <= mesh.n_tets <= high
    assert mesh.points.dtype == np.float64 and mesh.tets.dtype == np.int64
    assert mesh.signed_volumes().min() > 0
    validate_mesh(mesh.points, mesh.tets)  # one component, no flat element


@pytest.mark.parametrize("name", sorted(TET_RANGES))
def test_builder_landmarks_lie_in_the_material(built: dict[str, TetMesh], name: str) -> None:
    mesh = built[name]
    assert set(EXPECTED_LANDMARKS[name]) <= set(mesh.landmarks)
    for key, value in mesh.landmarks.items():
        assert value.ndim == 2 and value.shape[1] == 3, key
        if key.startswith(("cable_points", "effector", "contact_points", "neutral_fibre")):
            element, bary = locate_points(mesh, value, tolerance=1e-9)
            np.testing.assert_allclose(
                np.einsum("ki,kij->kj", bary, mesh.points[mesh.tets[element]]), value, atol=1e-9
            )
    fixed = in_box(mesh.points, mesh.landmarks["fixed_box"])
    assert 3 <= fixed.sum() < mesh.n_nodes / 4


def test_diamond_reference_landmarks(built: dict[str, TetMesh]) -> None:
    lm = built["diamond"].landmarks
    np.testing.assert_allclose(lm["effector"], [[0, 0, 125]])
    elbows = np.concatenate([lm[f"cable_points_{n}"] for n in range(4)])
    pulls = np.concatenate([lm[f"pull_points_{n}"] for n in range(4)])
    np.testing.assert_allclose(
        elbows, [[0, 97, 45], [-97, 0, 45], [0, -97, 45], [97, 0, 45]], atol=1e-12
    )
    np.testing.assert_allclose(
        pulls, [[0, 10, 30], [-10, 0, 30], [0, -10, 30], [10, 0, 30]], atol=1e-12
    )
    np.testing.assert_allclose(lm["fixed_box"], [[-15, -15, -40], [15, 15, 10]])


def test_trunk_cables_and_fibre(built: dict[str, TetMesh]) -> None:
    lm = built["trunk"].landmarks
    for n in range(8):
        z = lm[f"cable_points_{n}"][:, 2]
        np.testing.assert_allclose(np.diff(z), 17.5)
        assert z.max() > (150 if n < 4 else 80) and z.max() <= (195 if n < 4 else 97.5)
    np.testing.assert_allclose(lm["pull_points_0"], [[0, 10, 0]], atol=1e-12)
    np.testing.assert_allclose(lm["pull_points_3"], [[10, 0, 0]], atol=1e-12)
    assert lm["neutral_fibre"].shape == (21, 3)
    np.testing.assert_allclose(lm["effector"], [[0, 0, 195]])
    np.testing.assert_allclose(lm["fixed_box"], [[-20, -20, 0], [20, 20, 20]])


def test_soft_finger_cables_bend_both_ways(built: dict[str, TetMesh]) -> None:
    mesh = built["soft_finger"]
    low, high = mesh.landmarks["cable_points_0"], mesh.landmarks["cable_points_1"]
    assert low.shape == high.shape and len(low) >= 5
    assert np.all(low[:, 2] < 10.0) and np.all(high[:, 2] > 10.0)
    assert np.all(np.diff(low[:, 0]) > 0)  # ordered from the base to the tip
    contact = mesh.landmarks["contact_points"]
    assert contact.shape == (3, 3) and np.allclose(contact[:, 2], mesh.points[:, 2].min())


def test_pneunet_cavity_volume_is_the_analytical_chamber_volume(
    built: dict[str, TetMesh],
) -> None:
    mesh = built["pneunet"]
    boxes = pneunet_cavity_boxes()
    chamber_volumes = [float(np.prod(hi - lo)) for lo, hi in boxes]
    # Box-shaped chambers have flat walls, which the mesh reproduces exactly.
    for n, expected in enumerate(chamber_volumes):
        triangles = mesh.surfaces[f"cavity_{n}"]
        assert enclosed_volume(mesh.points, triangles) == pytest.approx(expected, rel=1e-9)
        # A closed surface: every edge is used once in each direction.
        edges = np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]])
        forward = {tuple(e) for e in edges.tolist()}
        assert len(forward) == len(edges)
        assert forward == {(b, a) for a, b in forward}
    total = enclosed_volume(mesh.points, mesh.surfaces["cavity"])
    assert total > 0
    assert total == pytest.approx(sum(chamber_volumes), rel=1e-9)
    # Cavity triangles are triangles of the volume mesh: their nodes are mesh nodes.
    assert mesh.surfaces["cavity"].max() < mesh.n_nodes


def test_builders_are_deterministic() -> None:
    a, b = trunk(mesh_size=8.0), trunk(mesh_size=8.0)
    np.testing.assert_array_equal(a.points, b.points)
    np.testing.assert_array_equal(a.tets, b.tets)


def test_builder_cleans_up_gmsh_also_on_failure(monkeypatch: pytest.MonkeyPatch) -> None:
    def fail(mesh_size: float) -> None:
        raise RuntimeError("meshing failed")

    monkeypatch.setattr("pliant.mesh.shapes.mesh_volumes", fail)
    with pytest.raises(RuntimeError, match="meshing failed"):
        trunk()
    assert not gmsh.isInitialized()


# A Finger design of Table 5.7's geometric box whose first surface mesh gmsh's 3-D Delaunay
# cannot recover ("Could not recover boundary mesh"): found by the 50000-design collection.
_HARD_FINGER = {
    "length": 39.67705236602058,
    "height": 20.019942905214503,
    "joint_height": 5.760204505886336,
}


def test_a_design_the_volume_mesher_rejects_is_meshed_with_the_fallback_surfaces(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    with monkeypatch.context() as patch:
        patch.setattr("pliant.mesh.gmsh_session._FALLBACK_2D", ())
        with pytest.raises(MeshingError, match="recover boundary"):
            soft_finger(**_HARD_FINGER)
    assert not gmsh.isInitialized()
    mesh = soft_finger(**_HARD_FINGER)
    validate_mesh(mesh.points, mesh.tets)
    assert mesh.n_tets > 0
    np.testing.assert_array_equal(mesh.tets, soft_finger(**_HARD_FINGER).tets)  # deterministic
    # the next design meshes with the usual options again
    np.testing.assert_array_equal(soft_finger().tets, soft_finger().tets)
    assert gmsh_session._overrides == {}


def test_builder_leaves_a_callers_gmsh_session_alone() -> None:
    gmsh.initialize(readConfigFiles=False, interruptible=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add("user_model")
        gmsh.option.setNumber("Mesh.MeshSizeMax", 42.0)
        mesh = trunk(mesh_size=8.0)
        assert mesh.n_tets > 0
        assert gmsh.isInitialized()
        assert gmsh.model.getCurrent() == "user_model"
        assert gmsh.option.getNumber("Mesh.MeshSizeMax") == 42.0
    finally:
        gmsh.finalize()


def test_finger_parameters_change_the_geometry() -> None:
    small = soft_finger(length=38.0, height=20.0, joint_height=5.0)
    large = soft_finger(length=42.0, height=22.0, joint_height=8.0)
    assert np.ptp(large.points[:, 0]) - np.ptp(small.points[:, 0]) == pytest.approx(12.0)
    assert large.signed_volumes().sum() > small.signed_volumes().sum()


def test_builders_reject_bad_parameters() -> None:
    with pytest.raises(ModelError, match="resolution"):
        soft_finger(resolution="medium")  # type: ignore[arg-type]
    with pytest.raises(ModelError, match="joint_height"):
        soft_finger(joint_height=19.0)
    with pytest.raises(ModelError, match="radius"):
        trunk(tip_radius=0.0)
    with pytest.raises(ModelError, match="chambers"):
        pneunet(n_chambers=30)


@pytest.mark.slow
@pytest.mark.parametrize(("resolution", "expected"), [("fine", 8895), ("superfine", 17852)])
def test_finger_resolutions_match_the_thesis_meshes(resolution: str, expected: int) -> None:
    mesh = soft_finger(resolution=resolution)  # type: ignore[arg-type]
    assert abs(mesh.n_tets - expected) < 0.1 * expected
    validate_mesh(mesh.points, mesh.tets)


# ---------------------------------------------------------------------------------------------
# Quality checks


def test_validate_accepts_a_good_mesh() -> None:
    validate_mesh(UNIT_TET_POINTS, UNIT_TET)


def test_inverted_element_is_reported_with_count_and_index() -> None:
    mesh = box_beam(nx=2, ny=1, nz=1)
    tets = mesh.tets.copy()
    tets[[3, 7]] = tets[[3, 7]][:, [1, 0, 2, 3]]
    with pytest.raises(InvertedElementError, match=r"2 element\(s\).*element 3"):
        validate_mesh(mesh.points, tets)
    repaired = fix_orientation(mesh.points, tets)
    assert (TetMesh(mesh.points, repaired).signed_volumes() > 0).all()
    validate_mesh(mesh.points, repaired)


def test_flat_element_is_degenerate() -> None:
    flat = UNIT_TET_POINTS.copy()
    flat[3] = [0.3, 0.3, 0.0]
    with pytest.raises(DegenerateElementError, match="element 0"):
        validate_mesh(flat, UNIT_TET)
    # Not zero volume, but a sliver far flatter than any mesher produces.
    sliver = UNIT_TET_POINTS.copy()
    sliver[3] = [0.3, 0.3, 1e-5]
    with pytest.raises(DegenerateElementError, match="quality"):
        validate_mesh(sliver, UNIT_TET)


def test_disconnected_mesh_reports_component_sizes() -> None:
    beam = box_beam(nx=2, ny=1, nz=1)
    points = np.concatenate([beam.points, UNIT_TET_POINTS + [500.0, 0, 0]])
    tets = np.concatenate([beam.tets, UNIT_TET + beam.n_nodes])
    with pytest.raises(DisconnectedMeshError, match=r"2 separate components of \[12, 1\]"):
        validate_mesh(points, tets)
    validate_mesh(points, tets, allow_disconnected=True)


@pytest.mark.parametrize(
    ("points", "tets", "message"),
    [
        (UNIT_TET_POINTS, np.array([[0, 1, 2, 4]]), "outside"),
        (UNIT_TET_POINTS, np.array([[0, 1, 2, -1]]), "outside"),
        (np.where(np.eye(4, 3, k=-3) == 1, np.nan, UNIT_TET_POINTS), UNIT_TET, "non-finite"),
        (UNIT_TET_POINTS, np.array([[0, 1, 2, 2]]), "repeat"),
        (UNIT_TET_POINTS[:, :2], UNIT_TET, "points"),
        (UNIT_TET_POINTS, UNIT_TET[:, :3], "tets"),
        (UNIT_TET_POINTS, np.zeros((0, 4), dtype=np.int64), "tets"),
        (UNIT_TET_POINTS, UNIT_TET.astype(float), "integer"),
        (np.concatenate([UNIT_TET_POINTS, [[5.0, 5, 5]]]), UNIT_TET, "no element"),
    ],
)
def test_malformed_arrays_raise_mesh_error(
    points: np.ndarray, tets: np.ndarray, message: str
) -> None:
    with pytest.raises(MeshError, match=message) as info:
        validate_mesh(points, tets)
    assert type(info.value) is MeshError


def test_remove_unused_nodes_renumbers() -> None:
    points = np.concatenate([[[9.0, 9, 9]], UNIT_TET_POINTS, [[7.0, 7, 7]]])
    new_points, new_tets = remove_unused_nodes(points, UNIT_TET + 1)
    np.testing.assert_array_equal(new_points, UNIT_TET_POINTS)
    np.testing.assert_array_equal(new_tets, UNIT_TET)


# ---------------------------------------------------------------------------------------------
# Point location


def test_locate_points_reconstructs_points_exactly() -> None:
    mesh = soft_finger(mesh_size=12.0)
    rng = np.random.default_rng(0)
    # Random points inside random elements, plus every node.
    elements = rng.integers(0, mesh.n_tets, 200)
    weights = rng.dirichlet(np.ones(4), 200)
    inside = np.einsum("ki,kij->kj", weights, mesh.points[mesh.tets[elements]])
    queries = np.concatenate([inside, mesh.points])
    element, bary = locate_points(mesh, queries)
    assert (bary >= -1e-10).all()
    np.testing.assert_allclose(bary.sum(axis=1), 1.0, atol=1e-14)
    reconstructed = np.einsum("ki,kij->kj", bary, mesh.points[mesh.tets[element]])
    np.testing.assert_allclose(reconstructed, queries, atol=1e-11)
    # Interior points away from faces are found in the very element they were drawn in.
    clear = weights.min(axis=1) > 1e-6
    np.testing.assert_array_equal(element[:200][clear], elements[clear])


def test_locating_points_the_nearest_centroids_miss_searches_as_every_element_would() -> None:
    """Points on and just off the surface of a graded mesh (the nearest centroids miss their
    element): the pruned search picks the element a search of every element picks."""
    from pliant.mesh.locate import _best_element

    mesh = soft_finger(mesh_size=12.0)
    rng = np.random.default_rng(1)
    surface = mesh.boundary_triangles()
    faces = surface[rng.integers(0, len(surface), 300)]
    weights = rng.dirichlet(np.ones(3), 300)
    on = np.einsum("ki,kij->kj", weights, mesh.points[faces])
    normals = np.cross(*(mesh.points[faces[:, 1:]] - mesh.points[faces[:, :1]]).transpose(1, 0, 2))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    queries = on + rng.uniform(-0.05, 0.3, (300, 1)) * normals
    element, _ = locate_points(mesh, queries, tolerance=1.0, outside="project")
    everything = np.arange(mesh.n_tets)
    expected = [_best_element(mesh, everything, x)[0] for x in queries]
    np.testing.assert_array_equal(element, expected)


def test_locate_points_clamps_near_points_and_rejects_far_ones() -> None:
    mesh = box_beam(nx=4, ny=2, nz=2)
    element, bary = locate_points(mesh, [100.0 + 1e-3, 10.0, 10.0], tolerance=0.01)
    assert (bary >= 0).all()
    x = bary[0] @ mesh.points[mesh.tets[element[0]]]
    np.testing.assert_allclose(x, [100.0, 10.0, 10.0], atol=1e-12)
    with pytest.raises(ModelError, match="outside the mesh"):
        locate_points(mesh, [[50.0, 10.0, 10.0], [150.0, 10.0, 10.0]])
    with pytest.raises(ModelError, match="finite"):
        locate_points(mesh, [np.nan, 0.0, 0.0])


# ---------------------------------------------------------------------------------------------
# File I/O


@pytest.mark.parametrize("suffix", [".msh", ".vtu", ".vtk"])
def test_save_load_round_trip(tmp_path: Path, suffix: str) -> None:
    mesh = box_beam(nx=3, ny=2, nz=1)
    path = tmp_path / f"beam{suffix}"
    save_mesh(mesh, path)
    assert [p.name for p in tmp_path.iterdir()] == [path.name]  # no temporary file left
    loaded = load_mesh(path)
    np.testing.assert_allclose(loaded.points, mesh.points, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(loaded.tets, mesh.tets)


def test_load_keeps_tetra_blocks_drops_unused_nodes_and_fixes_orientation(
    tmp_path: Path,
) -> None:
    beam = box_beam(nx=2, ny=1, nz=1)
    points = np.concatenate([beam.points, [[99.0, 99, 99]]])  # a node no element uses
    flipped = beam.tets[:, [0, 2, 1, 3]]  # the opposite orientation convention
    cells = [
        ("vertex", np.array([[0], [1]])),
        ("triangle", beam.boundary_triangles()),
        ("tetra", flipped[:5]),
        ("line", np.array([[0, 1]])),
        ("tetra", flipped[5:]),
    ]
    path = tmp_path / "mixed.vtk"
    meshio.write(path, meshio.Mesh(points, cells))
    loaded = load_mesh(path)
    assert loaded.n_nodes == beam.n_nodes and loaded.n_tets == beam.n_tets
    assert (loaded.signed_volumes() > 0).all()
    np.testing.assert_allclose(loaded.signed_volumes().sum(), 100 * 20 * 20)


def test_load_errors_name_the_cause(tmp_path: Path) -> None:
    with pytest.raises(MeshFileError, match="does not exist"):
        load_mesh(tmp_path / "missing.vtu")
    garbage = tmp_path / "garbage.vtk"
    garbage.write_bytes(np.random.default_rng(1).bytes(2000))
    with pytest.raises(MeshFileError, match="cannot read"):
        load_mesh(garbage)
    # A format meshio cannot tell or parse (Gmsh 1, SOFA's liver.msh) ends meshio's reading
    # with sys.exit: the same error, the interpreter alive.
    old_gmsh = tmp_path / "old.msh"
    old_gmsh.write_text("$NOD\n1\n1 0 0 0\n$ENDNOD\n$ELM\n0\n$ENDELM\n")
    with pytest.raises(MeshFileError, match="cannot read"):
        load_mesh(old_gmsh)
    surface_only = tmp_path / "surface.vtu"
    meshio.write(surface_only, meshio.Mesh(UNIT_TET_POINTS, [("triangle", np.array([[0, 1, 2]]))]))
    with pytest.raises(MeshFileError, match="no linear tetrahedra.*triangle"):
        load_mesh(surface_only)
    inverted_sliver = tmp_path / "bad.vtu"
    flat = UNIT_TET_POINTS.copy()
    flat[3] = [0.2, 0.2, 0.0]
    meshio.write(inverted_sliver, meshio.Mesh(flat, [("tetra", UNIT_TET)]))
    with pytest.raises(DegenerateElementError):
        load_mesh(inverted_sliver)


def test_save_errors_leave_nothing_behind(tmp_path: Path) -> None:
    mesh = box_beam(nx=1, ny=1, nz=1)
    with pytest.raises(MeshFileError, match="cannot write"):
        save_mesh(mesh, tmp_path / "beam.unknown-format")
    with pytest.raises(MeshFileError, match="cannot write"):
        save_mesh(mesh, tmp_path / "no" / "such" / "dir" / "beam.vtu")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    ("name", "nodes", "tets"),
    [
        ("Diamond_siliconeV0.vtu", 1628, 4147),
        ("Trunk_trunk.vtk", 709, 1972),
        ("MultiGaitRobot_full_quadriped_fine.vtk", 15787, 59296),
    ],
)
def test_load_reference_meshes(name: str, nodes: int, tets: int) -> None:
    path = REFERENCE_MESHES / name
    if not path.is_file():
        pytest.skip(f"reference mesh {path} is not available")
    mesh = load_mesh(path)
    assert (mesh.n_nodes, mesh.n_tets) == (nodes, tets)
    assert mesh.signed_volumes().min() > 0


def test_meshing_leaves_sigpipe_ignored() -> None:
    """gmsh's initialisation restores SIGPIPE's default action (end the process); meshing gives
    it back to Python, so that writing to a dead worker's pipe raises BrokenPipeError."""
    import signal

    from pliant.mesh import shapes

    shapes.diamond(mesh_size=30.0)  # a gmsh session opened and closed
    with open("/proc/self/status") as status:
        ignored = next(int(line.split()[1], 16) for line in status if line.startswith("SigIgn"))
    assert ignored & (1 << (signal.SIGPIPE - 1))
