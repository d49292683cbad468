"""Offscreen rendering of triangulated surfaces with Matplotlib's Agg backend.

Every figure here is a `matplotlib.figure.Figure` bound to its own `FigureCanvasAgg`; nothing
goes through `pyplot`, so rendering needs no display and leaves no global state behind.

A scene is a list of surfaces, each `(points (n, 3), triangles (k, 3), colour)`, plus named
markers (point sets, e.g. goal and effector) and named polylines (e.g. cable paths). All the
triangles of a scene go into one `Poly3DCollection`, which Matplotlib sorts back to front at draw
time (painter's algorithm), so several bodies occlude each other correctly.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import to_rgb
from matplotlib.figure import Figure
from mpl_toolkits.mplot3d import Axes3D
from mpl_toolkits.mplot3d.art3d import Poly3DCollection

Color = str | tuple[float, float, float]
Surface = tuple[np.ndarray, np.ndarray, Color]
"""One body to draw: points (n, 3), triangles (k, 3) into those points, colour."""

DEFAULT_VIEW = (25.0, -60.0)
"""Camera (elevation, azimuth) in degrees, as in `Axes3D.view_init`."""

BODY_COLOR = "#6a9fd4"

AMBIENT = 0.35
"""Share of the light that reaches every face whatever its orientation."""

# Markers and polylines are drawn over the surfaces: a cable runs inside the body and a goal may
# sit behind it, and both must stay visible.
_Z_SURFACE, _Z_LINES, _Z_MARKERS = 1, 2, 3


def offscreen_figure(width_in: float, height_in: float, *, dpi: float = 100.0) -> Figure:
    """A Figure of the given size in inches, bound to an Agg canvas (no display, no pyplot)."""
    fig = Figure(figsize=(width_in, height_in), dpi=dpi)
    FigureCanvasAgg(fig)
    return fig


def figure_to_image(fig: Figure) -> np.ndarray:
    """Draw `fig` with Agg and return its pixels as an RGB uint8 array (H, W, 3)."""
    canvas = fig.canvas
    if not isinstance(canvas, FigureCanvasAgg):
        canvas = FigureCanvasAgg(fig)
    canvas.draw()
    return np.asarray(canvas.buffer_rgba())[..., :3].copy()


def scene_bounds(point_sets: Iterable[np.ndarray], *, margin: float = 0.05) -> np.ndarray:
    """Axis-aligned box [[xmin, ymin, zmin], [xmax, ymax, zmax]] holding every point set.

    Pass the points of every frame of a sequence so that the camera stays still. The box grows
    by `margin` times its largest side on every side; a flat or point-like box is given a
    thickness so that the axes stay well defined.
    """
    stacked = [np.asarray(p, dtype=float).reshape(-1, 3) for p in point_sets]
    stacked = [p for p in stacked if p.size]
    if not stacked:
        raise ValueError("scene_bounds needs at least one non-empty point set")
    pts = np.concatenate(stacked)
    if not np.all(np.isfinite(pts)):
        raise ValueError("scene_bounds: points contain NaN or infinity")
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    extent = hi - lo
    size = float(extent.max())
    if size == 0.0:  # a single point: nothing sets a scale, take a unit box
        return np.stack([lo - 0.5, hi + 0.5])
    pad = margin * size
    # Sides thinner than 1 % of the largest get that much, so the box aspect stays non-zero.
    thin = np.maximum(0.0, 0.01 * size - extent) / 2
    return np.stack([lo - pad - thin, hi + pad + thin])


def headlight(view: tuple[float, float]) -> np.ndarray:
    """Unit light direction (towards the light) for a camera at `view` = (elev, azim) degrees.

    The light sits behind the viewer and above it, so it is fixed relative to the camera: every
    face the camera sees is lit, and the three visible faces of a box get distinct shades.
    """
    elev, azim = np.radians(view)
    eye = np.array([np.cos(elev) * np.cos(azim), np.cos(elev) * np.sin(azim), np.sin(elev)])
    right = np.array([-np.sin(azim), np.cos(azim), 0.0])
    up = np.cross(eye, right)
    light = eye + 0.6 * up
    return light / np.linalg.norm(light)


def lambert_shade(
    points: np.ndarray,
    triangles: np.ndarray,
    color: Color,
    light: np.ndarray,
    *,
    ambient: float = AMBIENT,
) -> np.ndarray:
    """RGBA face colours (k, 4) of a flat-shaded surface under a directional light.

    Lambert's cosine law, I = ambient + (1 - ambient) |n . l|, with n the unit face normal and
    l the unit direction towards the light. The absolute value lights both sides of a face, so
    open sheets and cavity walls read as well as closed outer surfaces.
    """
    p = points[triangles]
    normals = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    norm = np.linalg.norm(normals, axis=1, keepdims=True)
    # A zero-area face has no normal; it gets the ambient light only.
    normals = np.divide(normals, norm, out=np.zeros_like(normals), where=norm > 0)
    intensity = ambient + (1.0 - ambient) * np.abs(normals @ light)
    rgba = np.ones((len(triangles), 4))
    rgba[:, :3] = intensity[:, None] * np.asarray(to_rgb(color))
    return rgba


def apply_camera(
    ax: Axes3D, bounds: np.ndarray, view: tuple[float, float], vertical: str = "z"
) -> None:
    """Set limits to `bounds`, equal scale on the three axes, orthographic camera at `view`
    with the axis `vertical` ("x", "y" or "z") drawn upwards."""
    bounds = np.asarray(bounds, dtype=float)
    if bounds.shape != (2, 3) or not np.all(bounds[1] > bounds[0]):
        raise ValueError(
            f"bounds must be [[xmin, ymin, zmin], [xmax, ymax, zmax]] with max > min, "
            f"got {bounds.tolist()}"
        )
    ax.set_xlim(bounds[0, 0], bounds[1, 0])
    ax.set_ylim(bounds[0, 1], bounds[1, 1])
    ax.set_zlim(bounds[0, 2], bounds[1, 2])
    # A box aspect equal to the extents gives one length unit the same size on every axis.
    ax.set_box_aspect(bounds[1] - bounds[0])
    ax.set_proj_type("ortho")
    ax.view_init(elev=view[0], azim=view[1], vertical_axis=vertical)


def _check_surface(points: np.ndarray, triangles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    points = np.asarray(points, dtype=float)
    triangles = np.asarray(triangles)
    if points.ndim != 2 or points.shape[1] != 3:
        raise ValueError(f"surface points must have shape (n, 3), got {points.shape}")
    if not np.all(np.isfinite(points)):
        raise ValueError("surface points contain NaN or infinity")
    if triangles.ndim != 2 or triangles.shape[1] != 3 or not np.issubdtype(triangles.dtype, int):
        raise ValueError(
            f"triangles must be integers of shape (k, 3), got {triangles.dtype} {triangles.shape}"
        )
    if triangles.size and (triangles.min() < 0 or triangles.max() >= len(points)):
        raise ValueError(
            f"triangle indices must lie in [0, {len(points)}), "
            f"got [{triangles.min()}, {triangles.max()}]"
        )
    return points, triangles


def _named_points(
    named: Mapping[str, tuple[np.ndarray, Color]] | None,
) -> dict[str, tuple[np.ndarray, Color]]:
    result = {}
    for name, (pts, color) in (named or {}).items():
        pts = np.asarray(pts, dtype=float)
        if pts.ndim not in (1, 2) or pts.shape[-1] != 3:
            raise ValueError(f"points of {name!r} must have shape (3,) or (k, 3), got {pts.shape}")
        result[name] = (pts.reshape(-1, 3), color)
    return result


def draw_scene(
    ax: Axes3D,
    surfaces: Sequence[Surface],
    *,
    markers: Mapping[str, tuple[np.ndarray, Color]] | None = None,
    lines: Mapping[str, tuple[np.ndarray, Color]] | None = None,
    view: tuple[float, float] = DEFAULT_VIEW,
    bounds: np.ndarray | None = None,
    edgecolor: Color | None = None,
    legend: bool = True,
    vertical: str = "z",
) -> None:
    """Draw surfaces, markers and polylines into a 3D Axes.

    Args:
        ax: the Axes3D to draw into.
        surfaces: bodies `(points (n, 3), triangles (k, 3), colour)`, shaded and depth-sorted
            together.
        markers: named point sets `name -> (points (k, 3), colour)`, drawn as dots on top.
        lines: named polylines `name -> (points (k, 3), colour)`, drawn on top.
        view: camera (elevation, azimuth) in degrees.
        bounds: [[xmin, ymin, zmin], [xmax, ymax, zmax]]; keep it fixed across the frames of a
            sequence. By default the box around everything drawn.
        edgecolor: colour of the triangle edges; None draws no mesh lines.
        legend: label the markers and lines with their names.
        vertical: the axis drawn upwards (a scene under gravity along -y: "y").
    """
    markers, lines = _named_points(markers), _named_points(lines)
    checked = [(*_check_surface(p, t), c) for p, t, c in surfaces]
    if bounds is None:
        named = [p for p, _ in (*markers.values(), *lines.values())]
        bounds = scene_bounds([p for p, _, _ in checked] + named)
    apply_camera(ax, bounds, view, vertical)
    ax.computed_zorder = False
    ax.set_axis_off()

    light = headlight(view)
    verts = [p[t] for p, t, _ in checked]
    if verts:
        faces = np.concatenate(verts)
        colors = np.concatenate([lambert_shade(p, t, c, light) for p, t, c in checked])
        # Without edges, antialiasing leaves hairline seams between triangles; edges in the
        # face colour close them.
        edges, width = (colors, 0.6) if edgecolor is None else (edgecolor, 0.4)
        ax.add_collection3d(
            Poly3DCollection(
                faces,
                facecolors=colors,
                edgecolors=edges,
                linewidths=width,
                zsort="average",
                zorder=_Z_SURFACE,
            )
        )
    for name, (pts, color) in lines.items():
        ax.plot(*pts.T, color=color, linewidth=2.0, label=name, zorder=_Z_LINES)
    for name, (pts, color) in markers.items():
        ax.scatter(
            *pts.T,
            color=color,
            s=40,
            depthshade=False,
            edgecolors="black",
            linewidths=0.6,
            label=name,
            zorder=_Z_MARKERS,
        )
    if legend and (markers or lines):
        ax.legend(loc="upper right", fontsize="small", framealpha=0.8)


def render_surface(
    points: np.ndarray,
    triangles: np.ndarray,
    *,
    ax: Axes3D | None = None,
    color: Color = BODY_COLOR,
    edgecolor: Color | None = None,
    view: tuple[float, float] = DEFAULT_VIEW,
    bounds: np.ndarray | None = None,
    extras: Sequence[Surface] | None = None,
) -> Axes3D:
    """Draw one shaded triangulated surface, plus optional further bodies, into a 3D Axes.

    Args:
        points: (n, 3) node coordinates.
        triangles: (k, 3) node indices, e.g. `TetMesh.boundary_triangles()`.
        ax: the Axes3D to draw into; by default a new 640x480 offscreen figure
            (reach it with `ax.figure`).
        color: body colour before shading.
        edgecolor: colour of the triangle edges; None draws no mesh lines.
        view: camera (elevation, azimuth) in degrees.
        bounds: [[xmin, ymin, zmin], [xmax, ymax, zmax]]; by default the box around the bodies.
        extras: further bodies `(points, triangles, colour)`, depth-sorted with this one.

    Returns:
        The Axes drawn into.
    """
    if ax is None:
        ax = offscreen_figure(6.4, 4.8).add_axes((0.0, 0.0, 1.0, 1.0), projection="3d")
    surfaces = [(points, triangles, color), *(extras or [])]
    draw_scene(ax, surfaces, view=view, bounds=bounds, edgecolor=edgecolor)
    return ax


def render_scene(
    surfaces: Sequence[Surface],
    *,
    title: str | None = None,
    markers: Mapping[str, tuple[np.ndarray, Color]] | None = None,
    lines: Mapping[str, tuple[np.ndarray, Color]] | None = None,
    view: tuple[float, float] = DEFAULT_VIEW,
    bounds: np.ndarray | None = None,
    size: tuple[int, int] = (640, 480),
    edgecolor: Color | None = None,
    legend: bool = True,
    vertical: str = "z",
) -> np.ndarray:
    """Render several bodies, markers and polylines to an RGB image.

    Arguments as in `draw_scene`; `title` is written at the top and `size` is the image
    (width, height) in pixels.

    Returns:
        RGB uint8 image of shape (height, width, 3) on a white background.
    """
    width, height = size
    if width < 1 or height < 1:
        raise ValueError(f"image size must be positive, got {size}")
    dpi = 100.0
    fig = offscreen_figure(width / dpi, height / dpi, dpi=dpi)
    ax = fig.add_axes((0.0, 0.0, 1.0, 1.0), projection="3d")
    draw_scene(
        ax,
        surfaces,
        markers=markers,
        lines=lines,
        view=view,
        bounds=bounds,
        edgecolor=edgecolor,
        legend=legend,
        vertical=vertical,
    )
    if title:
        fig.text(0.5, 0.98, title, ha="center", va="top", fontsize="medium")
    return figure_to_image(fig)


def render_frame(
    points: np.ndarray,
    triangles: np.ndarray,
    *,
    color: Color = BODY_COLOR,
    **options,
) -> np.ndarray:
    """Render one body to an RGB uint8 image (height, width, 3); `options` (title, markers, lines,
    view, bounds, size, edgecolor, legend) as in `render_scene`.

    For a video, compute `bounds` once with `scene_bounds` over all frames so the camera does
    not jump.
    """
    return render_scene([(points, triangles, color)], **options)
