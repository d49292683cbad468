"""Tests of offscreen rendering, animation and ParaView output, and report plots."""

from __future__ import annotations

import itertools
import json
import xml.etree.ElementTree as ET

import imageio.v3 as iio
import meshio
import numpy as np
import pytest

from pliant.mesh.tetmesh import TetMesh
from pliant.viz import (
    VtuSeriesWriter,
    atomic_path,
    convergence_order,
    plot_convergence,
    plot_loglog,
    plot_trajectory,
    render_frame,
    render_scene,
    render_surface,
    save_figure,
    save_gif,
    save_png,
    scene_bounds,
)

RED = np.array([255, 0, 0])


def unit_cube() -> TetMesh:
    """The unit cube cut into six tetrahedra along its main diagonal (Kuhn triangulation)."""
    points = np.array(list(itertools.product((0.0, 1.0), repeat=3)))  # index = 4x + 2y + z
    tets = []
    for axes in itertools.permutations(range(3)):
        corner, path = np.zeros(3, dtype=int), [0]
        for axis in axes:
            corner[axis] = 1
            path.append(int(corner @ [4, 2, 1]))
        tets.append(path)
    tets = np.array(tets)
    p = points[tets]
    volume = np.einsum(
        "ij,ij->i", np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), p[:, 3] - p[:, 0]
    )
    tets[volume < 0] = tets[volume < 0][:, [0, 2, 1, 3]]
    return TetMesh(points, tets)


def object_mask(image: np.ndarray) -> np.ndarray:
    """Pixels that are not the white background."""
    return np.any(image < 245, axis=-1)


def count_colour(image: np.ndarray, rgb: np.ndarray, tol: int = 30) -> int:
    return int(np.sum(np.all(np.abs(image.astype(int) - rgb) <= tol, axis=-1)))


@pytest.fixture(scope="module")
def cube() -> TetMesh:
    return unit_cube()


def test_unit_cube_fixture_is_a_valid_mesh(cube):
    assert np.all(cube.signed_volumes() > 0)
    assert np.isclose(cube.signed_volumes().sum(), 1.0)
    assert cube.boundary_triangles().shape == (12, 3)


@pytest.mark.parametrize("size", [(640, 480), (333, 217)])
def test_render_frame_has_requested_size_and_draws_the_object(cube, size):
    image = render_frame(cube.points, cube.boundary_triangles(), size=size)
    width, height = size
    assert image.shape == (height, width, 3)
    assert image.dtype == np.uint8
    mask = object_mask(image)
    # The cube covers a sizeable, bounded part of the frame, around its middle.
    assert 0.05 < mask.mean() < 0.8
    rows, cols = np.nonzero(mask)
    assert abs(rows.mean() - height / 2) < 0.15 * height
    assert abs(cols.mean() - width / 2) < 0.15 * width
    assert not mask[0].any() and not mask[-1].any() and not mask[:, 0].any()


def test_lambert_shading_gives_visible_faces_distinct_shades(cube):
    image = render_frame(cube.points, cube.boundary_triangles(), size=(320, 240))
    pixels = image[object_mask(image)]
    shades, counts = np.unique(pixels, axis=0, return_counts=True)
    # Three faces of a cube are visible; each is one flat shade covering many pixels.
    big = shades[counts > 0.1 * len(pixels)]
    assert len(big) == 3
    assert len({tuple(s) for s in big}) == 3


def test_marker_of_another_colour_appears_where_placed(cube):
    triangles = cube.boundary_triangles()
    bounds = scene_bounds([cube.points], margin=0.3)
    plain = render_frame(cube.points, triangles, bounds=bounds, legend=False)
    marked = render_frame(
        cube.points,
        triangles,
        bounds=bounds,
        markers={"goal": (np.array([[1.0, 0.0, 1.0]]), "red")},
        legend=False,
    )
    assert count_colour(plain, RED) == 0
    assert count_colour(marked, RED) > 20
    # Only the marker's neighbourhood changes.
    changed = np.any(plain != marked, axis=-1)
    rows, cols = np.nonzero(changed)
    assert np.ptp(rows) < 30 and np.ptp(cols) < 30


def test_lines_title_and_legend_render(cube):
    cable = np.array([[0.5, 0.5, 0.0], [0.5, 0.5, 1.0]])
    image = render_frame(
        cube.points,
        cube.boundary_triangles(),
        title="t = 0.10 s",
        markers={"effector": (np.array([[0.5, 0.5, 1.0]]), "gold")},
        lines={"cable": (cable, "black")},
        edgecolor="black",
    )
    assert image.shape == (480, 640, 3)
    assert count_colour(image, np.array([0, 0, 0]), tol=40) > 50


def test_fixed_bounds_keep_the_camera_still(cube):
    triangles = cube.boundary_triangles()
    moved = cube.points + np.array([3.0, 0.0, 0.0])
    bounds = scene_bounds([cube.points, moved])
    first = object_mask(render_frame(cube.points, triangles, bounds=bounds, size=(320, 240)))
    second = object_mask(render_frame(moved, triangles, bounds=bounds, size=(320, 240)))
    # Under one camera the moved body lands elsewhere in the image ...
    assert (first & second).sum() < 0.2 * first.sum()
    assert np.nonzero(second)[1].mean() > np.nonzero(first)[1].mean()
    # ... whereas a camera framing each frame on its own body shows no motion at all.
    own_first = object_mask(render_frame(cube.points, triangles, size=(320, 240)))
    own_second = object_mask(render_frame(moved, triangles, size=(320, 240)))
    np.testing.assert_array_equal(own_first, own_second)


def test_two_bodies_in_one_scene(cube):
    triangles = cube.boundary_triangles()
    other = cube.points + np.array([2.0, 0.0, 0.0])
    both = render_scene([(cube.points, triangles, "tab:blue"), (other, triangles, "red")])
    assert count_colour(both, RED, tol=120) > 100
    one = render_scene(
        [(cube.points, triangles, "tab:blue")], bounds=scene_bounds([cube.points, other])
    )
    assert object_mask(both).sum() > 1.5 * object_mask(one).sum()


def test_render_surface_draws_into_given_axes(cube):
    ax = render_surface(
        cube.points,
        cube.boundary_triangles(),
        extras=[(cube.points + 2, cube.boundary_triangles(), "red")],
    )
    assert len(ax.collections) == 1
    assert len(ax.collections[0].get_facecolor()) == 24


def test_scene_bounds_hold_every_frame_and_thicken_flat_scenes():
    frames = [np.array([[0.0, 0.0, 0.0], [100.0, 20.0, 0.0]]), np.array([[50.0, -10.0, 0.0]])]
    lo, hi = scene_bounds(frames, margin=0.1)
    assert np.all(lo <= [0.0, -10.0, 0.0]) and np.all(hi >= [100.0, 20.0, 0.0])
    np.testing.assert_allclose(lo[:2], [-10.0, -20.0])
    # A planar scene gets 1 % of its size as thickness (plus the margin).
    assert hi[2] - lo[2] == pytest.approx(1.0 + 2 * 10.0)


def test_render_rejects_bad_input(cube):
    with pytest.raises(ValueError, match="indices"):
        render_frame(cube.points, np.array([[0, 1, 99]]))
    with pytest.raises(ValueError, match=r"\(n, 3\)"):
        render_frame(cube.points[:, :2], cube.boundary_triangles())
    with pytest.raises(ValueError, match="bounds"):
        render_frame(cube.points, cube.boundary_triangles(), bounds=np.zeros((2, 3)))
    with pytest.raises(ValueError, match="'goal'"):
        render_frame(cube.points, cube.boundary_triangles(), markers={"goal": (np.zeros(2), "r")})


def test_gif_round_trip_keeps_frame_count(tmp_path):
    frames = [np.full((24, 32, 3), 30 * i, dtype=np.uint8) for i in range(7)]
    path = save_gif(frames, tmp_path / "anim.gif", fps=10)
    read = iio.imread(path, index=None)
    assert read.shape[:3] == (7, 24, 32)
    assert iio.immeta(path)["duration"] == 100
    assert [p.name for p in tmp_path.iterdir()] == ["anim.gif"]


def test_gif_rejects_mixed_frame_sizes(tmp_path):
    frames = [np.zeros((4, 4, 3), np.uint8), np.zeros((5, 4, 3), np.uint8)]
    with pytest.raises(ValueError, match="same shape"):
        save_gif(frames, tmp_path / "bad.gif")
    assert not list(tmp_path.iterdir())


def test_png_round_trip(tmp_path):
    image = np.random.default_rng(0).integers(0, 256, (10, 12, 3), dtype=np.uint8)
    path = save_png(image, tmp_path / "sub" / "frame.png")
    np.testing.assert_array_equal(iio.imread(path), image)


def test_a_figure_is_kept_in_256_colours_looking_the_same_and_smaller(tmp_path):
    import io

    from matplotlib.figure import Figure
    from PIL import Image

    fig = Figure(figsize=(5, 3.5))
    ax = fig.add_subplot()
    x = np.linspace(0.0, 6.0, 400)
    ax.contourf(*np.meshgrid(x, x), np.sin(x)[:, None] * np.cos(x)[None, :], levels=30)
    ax.plot(x, 3 + np.sin(3 * x), "k-", lw=0.7, label="anti-aliased line")
    ax.legend()
    ax.set_title("a contour plot and a line")
    truecolour = io.BytesIO()
    fig.savefig(truecolour, format="png", dpi=100)
    reference = np.asarray(Image.open(truecolour).convert("RGB"), dtype=float)

    path = save_figure(fig, tmp_path / "sub" / "figure.png", dpi=100)
    kept = Image.open(path)
    assert kept.mode == "P" and len(kept.getcolors(maxcolors=256)) <= 256
    pixels = np.asarray(kept.convert("RGB"), dtype=float)
    assert pixels.shape == reference.shape
    # At most a few grey levels off on average, nowhere a different colour.
    assert np.abs(pixels - reference).mean() < 0.5
    assert np.quantile(np.abs(pixels - reference).max(axis=2), 0.999) < 16
    assert path.stat().st_size < 0.6 * truecolour.getbuffer().nbytes
    again = save_figure(fig, tmp_path / "again.png", dpi=100)
    assert again.read_bytes() == path.read_bytes()


def test_atomic_path_leaves_nothing_when_writing_fails(tmp_path):
    target = tmp_path / "out.txt"
    target.write_text("old")
    with pytest.raises(RuntimeError), atomic_path(target) as tmp:
        tmp.write_text("half")
        raise RuntimeError("writer crashed")
    assert target.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["out.txt"]


def test_a_json_report_is_written_whole_or_not_at_all(tmp_path):
    """pliant.files.write_json: the report, read back; one that cannot be serialised leaves
    the previous file as it was and no temporary file beside it."""
    from pliant.files import write_json

    target = tmp_path / "report.json"
    write_json(target, {"a": [1, 2.5], "b": None})
    assert json.loads(target.read_text()) == {"a": [1, 2.5], "b": None}
    with pytest.raises(TypeError):
        write_json(target, {"a": object()})
    assert json.loads(target.read_text()) == {"a": [1, 2.5], "b": None}
    assert [p.name for p in tmp_path.iterdir()] == ["report.json"]


def test_vtu_series_round_trip(tmp_path, cube):
    times = [0.0, 0.05, 0.1]
    frames = []
    with VtuSeriesWriter(tmp_path / "vtk", "cube", cube.tets) as series:
        for t in times:
            u = t * np.column_stack([cube.points[:, 2], np.zeros(8), -cube.points[:, 0]])
            data = {"displacement": u, "pressure": np.arange(8.0) * t}
            series.write(t, cube.points + u, data)
            frames.append((cube.points + u, data))

    directory = tmp_path / "vtk"
    pvd = ET.parse(directory / "cube.pvd").getroot()
    assert pvd.get("type") == "Collection"
    datasets = pvd.findall("./Collection/DataSet")
    assert [float(d.get("timestep")) for d in datasets] == times
    assert sorted(p.name for p in directory.iterdir()) == sorted(
        ["cube.pvd"] + [d.get("file") for d in datasets]
    )
    for dataset, (points, data) in zip(datasets, frames, strict=True):
        mesh = meshio.read(directory / dataset.get("file"))
        np.testing.assert_allclose(mesh.points, points)
        np.testing.assert_array_equal(mesh.cells_dict["tetra"], cube.tets)
        assert mesh.point_data.keys() == data.keys()
        for name, value in data.items():
            np.testing.assert_allclose(mesh.point_data[name], value)


def test_vtu_series_rejects_misuse(tmp_path, cube):
    series = VtuSeriesWriter(tmp_path, "s", cube.tets)
    series.write(0.0, cube.points)
    with pytest.raises(ValueError, match="time"):
        series.write(0.0, cube.points)
    with pytest.raises(ValueError, match="point data 'u'"):
        series.write(1.0, cube.points, {"u": np.zeros(3)})
    with pytest.raises(ValueError, match="only 4 points"):
        series.write(1.0, cube.points[:4])
    series.close()
    with pytest.raises(RuntimeError, match="closed"):
        series.write(2.0, cube.points)
    assert len(ET.parse(tmp_path / "s.pvd").findall("./Collection/DataSet")) == 1


def _assert_png_with_content(path):
    image = iio.imread(path)
    assert image.ndim == 3 and image.shape[0] > 100 and image.shape[1] > 100
    assert object_mask(image[..., :3]).mean() > 0.01


def test_plots_write_png(tmp_path):
    rng = np.random.default_rng(1)
    goals = rng.uniform(0.0, 50.0, (15, 3))
    reached = goals + rng.normal(0.0, 1.0, goals.shape)
    _assert_png_with_content(plot_trajectory(goals, reached, tmp_path / "traj.png", title="reach"))

    elements = np.array([1e2, 1e3, 1e4])
    speeds = {"Pliant": (elements, 2e5 / elements), "SOFA": (elements, 5e4 / elements)}
    path = plot_loglog(
        speeds, tmp_path / "speed.png", xlabel="elements", ylabel="steps / s", title="speed"
    )
    _assert_png_with_content(path)

    hs = np.array([0.4, 0.2, 0.1, 0.05])
    errors = {"L2": 3 * hs**2, "energy": 2 * hs}
    path = plot_convergence(hs, errors, tmp_path / "conv.png", expected_order=2)
    _assert_png_with_content(path)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["conv.png", "speed.png", "traj.png"]


def test_convergence_order_recovers_a_power_law():
    hs = np.array([0.5, 0.25, 0.125])
    assert convergence_order(hs, 7.0 * hs**1.5) == pytest.approx(1.5)
    with pytest.raises(ValueError, match="positive"):
        convergence_order(hs, np.array([1.0, 0.0, 0.1]))


def test_shape_surfaces_enclose_their_shapes() -> None:
    """Drawn solids are closed and outward: their enclosed volume is the shape's (a UV sphere
    of 12 rings is inscribed, a few % smaller), at the pose given."""
    from pliant.constraints.cavity import enclosed_volume
    from pliant.geometry.collision import Box, Capsule, Plane, Sphere
    from pliant.viz.shapes import shape_surface

    rot = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    pts, tris = shape_surface(Box([1.0, 2.0, 3.0]), position=[5.0, 0.0, 0.0], rotation=rot)
    assert enclosed_volume(pts, tris) == pytest.approx(48.0, rel=1e-12)
    assert np.allclose(pts.mean(axis=0), [5.0, 0.0, 0.0])
    pts, tris = shape_surface(Sphere(2.0))
    assert 0.95 < enclosed_volume(pts, tris) / (4 / 3 * np.pi * 8.0) < 1.0
    pts, tris = shape_surface(Capsule(1.0, 2.0))
    exact = np.pi * 4.0 + 4 / 3 * np.pi
    assert 0.95 < enclosed_volume(pts, tris) / exact < 1.0
    pts, _ = shape_surface(Plane(point=(0.0, 0.0, -1.0)), extent=10.0, centre=[3.0, 4.0, 7.0])
    assert np.allclose(pts[:, 2], -1.0) and np.allclose(pts.mean(axis=0)[:2], [3.0, 4.0])


def test_robot_camera_draws_the_axis_of_gravity_vertical() -> None:
    """The Trunk scenes fall along -y, the others along -z: the camera puts that axis up, so
    a floor under the Trunk is drawn as a floor, not as a wall."""
    from pliant import robots
    from pliant.viz.model_view import RobotCamera

    assert RobotCamera(robots.build("trunk_cube")).vertical == "y"
    assert RobotCamera(robots.build("diamond")).vertical == "z"
