"""Image, animation and ParaView output, each file written atomically.

A file is first written under a temporary name in its own directory and then moved over the
target with `os.replace`, so a reader (or a crash) never sees half a file.
"""

from __future__ import annotations

import io
import os
import xml.etree.ElementTree as ET
from collections.abc import Iterable, Mapping
from pathlib import Path
from types import TracebackType
from typing import TYPE_CHECKING, Self

import imageio.v3 as iio
import meshio
import numpy as np
from PIL import Image

from pliant.files import atomic_path  # re-exported: the writers here and pliant.viz use it

if TYPE_CHECKING:
    from matplotlib.figure import Figure


def _check_image(image: np.ndarray, what: str) -> np.ndarray:
    image = np.asarray(image)
    if image.dtype != np.uint8 or image.ndim != 3 or image.shape[2] not in (3, 4):
        raise ValueError(
            f"{what} must be a uint8 array of shape (H, W, 3) or (H, W, 4), "
            f"got {image.dtype} {image.shape}"
        )
    return image


def save_png(image: np.ndarray, path: str | os.PathLike) -> Path:
    """Write an RGB(A) uint8 image (H, W, 3|4) as PNG; returns the path written."""
    image = _check_image(image, "image")
    with atomic_path(path) as tmp:
        iio.imwrite(tmp, image, extension=".png")
    return Path(path)


def save_figure(fig: Figure, path: str | os.PathLike, *, dpi: float = 120) -> Path:
    """Write a Matplotlib figure as a PNG of at most 256 colours; returns the path written.

    Report figures are flat colours and anti-aliased edges: a palette of the figure's 256 most
    used colours (median cut, no dithering) shows no visible difference and makes the file
    about a third of Matplotlib's truecolour PNG, which is what keeps the committed results
    small. The same figure always gives the same bytes.
    """
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=dpi)
    image = Image.open(buffer).convert("RGB")
    palette = image.quantize(colors=256, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE)
    with atomic_path(path) as tmp:
        palette.save(tmp, format="png", optimize=True)
    return Path(path)


def save_gif(frames: Iterable[np.ndarray], path: str | os.PathLike, fps: float = 20) -> Path:
    """Write equally sized RGB(A) uint8 frames as a looping GIF; returns the path written.

    GIF stores frame delays in hundredths of a second, so the rate is rounded to that. Pillow
    merges a frame identical to the one before it into a longer frame.
    """
    frames = [_check_image(f, f"frame {i}") for i, f in enumerate(frames)]
    if not frames:
        raise ValueError("save_gif needs at least one frame")
    shapes = {f.shape for f in frames}
    if len(shapes) > 1:
        raise ValueError(f"all frames must have the same shape, got {sorted(shapes)}")
    if not fps > 0:
        raise ValueError(f"fps must be positive, got {fps}")
    with atomic_path(path) as tmp:
        iio.imwrite(
            tmp, np.stack(frames), extension=".gif", plugin="pillow", duration=1000 / fps, loop=0
        )
    return Path(path)


class VtuSeriesWriter:
    """A time series of meshes for ParaView: one .vtu per frame and a .pvd index.

    Files are `directory/{stem}_{index:05d}.vtu` and `directory/{stem}.pvd`. The .pvd is
    rewritten after every frame, so the series opens in ParaView even if the run stops early.

    Args:
        directory: output folder, created if missing.
        stem: common file name prefix.
        tets: (m, k) node indices of the cells, the same for every frame (e.g.
            `TetMesh.tets`; a body's `vtk_cells()` gives its cells and their type).
        cell_type: meshio's name of the cells: "tetra" (k = 4), "line" (k = 2), ...

    Example:
        with VtuSeriesWriter("out", "finger", mesh.tets) as series:
            for t, x, v in trajectory:
                series.write(t, x, {"velocity": v})
    """

    _CELL_SIZES = {"tetra": 4, "line": 2, "triangle": 3, "hexahedron": 8}

    def __init__(
        self, directory: str | os.PathLike, stem: str, tets: np.ndarray, cell_type: str = "tetra"
    ) -> None:
        tets = np.asarray(tets)
        size = self._CELL_SIZES.get(cell_type)
        if size is None:
            raise ValueError(
                f"cell_type must be one of {sorted(self._CELL_SIZES)}, got {cell_type!r}"
            )
        if tets.ndim != 2 or tets.shape[1] != size or not np.issubdtype(tets.dtype, np.integer):
            raise ValueError(
                f"{cell_type} cells must be integers of shape (m, {size}), got {tets.dtype}"
                f" {tets.shape}"
            )
        self.cell_type = cell_type
        if not stem or Path(stem).name != stem:
            raise ValueError(f"stem must be a plain file name prefix, got {stem!r}")
        self.directory = Path(directory)
        self.directory.mkdir(parents=True, exist_ok=True)
        self.stem = stem
        self.tets = tets.astype(np.int64)
        self.times: list[float] = []
        self.files: list[Path] = []
        self._closed = False

    @property
    def pvd_path(self) -> Path:
        return self.directory / f"{self.stem}.pvd"

    def write(
        self,
        time: float,
        points: np.ndarray,
        point_data: Mapping[str, np.ndarray] | None = None,
    ) -> Path:
        """Write one frame at `time`; returns the .vtu path.

        Args:
            time: simulation time; must increase from frame to frame.
            points: (n, 3) node positions (deformed configuration).
            point_data: named nodal fields, each (n,) or (n, c), e.g. displacement, velocity.
        """
        if self._closed:
            raise RuntimeError(f"VtuSeriesWriter for {self.pvd_path} is closed")
        time = float(time)
        if not np.isfinite(time) or (self.times and time <= self.times[-1]):
            last = self.times[-1] if self.times else None
            raise ValueError(f"frame time must be finite and above the last ({last}), got {time}")
        points = np.asarray(points, dtype=float)
        if points.ndim != 2 or points.shape[1] != 3:
            raise ValueError(f"points must have shape (n, 3), got {points.shape}")
        if self.tets.size and self.tets.max() >= len(points):
            raise ValueError(
                f"tets index node {self.tets.max()} but only {len(points)} points were given"
            )
        data = {name: np.asarray(value) for name, value in (point_data or {}).items()}
        for name, value in data.items():
            if value.shape[:1] != (len(points),) or value.ndim > 2:
                raise ValueError(
                    f"point data {name!r} must have shape (n,) or (n, c) with n = {len(points)}, "
                    f"got {value.shape}"
                )
        mesh = meshio.Mesh(points, [(self.cell_type, self.tets)], point_data=data)
        path = self.directory / f"{self.stem}_{len(self.files):05d}.vtu"
        with atomic_path(path) as tmp:
            meshio.write(tmp, mesh, file_format="vtu")
        self.times.append(time)
        self.files.append(path)
        self._write_pvd()
        return path

    def _write_pvd(self) -> None:
        root = ET.Element("VTKFile", type="Collection", version="0.1", byte_order="LittleEndian")
        collection = ET.SubElement(root, "Collection")
        for time, path in zip(self.times, self.files, strict=True):
            ET.SubElement(
                collection, "DataSet", timestep=repr(time), group="", part="0", file=path.name
            )
        ET.indent(root)
        with atomic_path(self.pvd_path) as tmp:
            ET.ElementTree(root).write(tmp, encoding="utf-8", xml_declaration=True)

    def close(self) -> None:
        """Finish the series: write the .pvd index (also for an empty series)."""
        if not self._closed:
            self._write_pvd()
            self._closed = True

    def __enter__(self) -> Self:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()
