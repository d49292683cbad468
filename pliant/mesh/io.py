"""Reading and writing tetrahedral meshes in any format meshio knows (.msh, .vtu, .vtk, ...)."""

from __future__ import annotations

import contextlib
import io
import os
import tempfile
from pathlib import Path

import meshio
import numpy as np

from pliant.errors import MeshFileError
from pliant.files import replace
from pliant.mesh.quality import fix_orientation, remove_unused_nodes, validate_mesh
from pliant.mesh.tetmesh import TetMesh


def read_meshio(path: str | os.PathLike, file_format: str | None = None) -> meshio.Mesh:
    """``meshio.read``, its failures one MeshFileError: meshio prints its complaints and ends
    the interpreter (``sys.exit``) on some files it cannot parse (an old Gmsh format, a format
    it cannot tell). A ``.msh`` file (ANSYS Fluent's, as meshio writes it, or Gmsh's) is read
    through :class:`_Ended`: meshio's Fluent reader skips to a closing bracket one
    byte at a time and would loop forever past the end of a truncated file (found by the
    crash-prone property test)."""
    if file_format is None and Path(path).suffix.lower() == ".msh":
        return _read_msh(path)
    said = io.StringIO()
    try:
        with contextlib.redirect_stdout(said), contextlib.redirect_stderr(said):
            return meshio.read(path, file_format=file_format)
    except (Exception, SystemExit) as exc:  # meshio signals malformed input many ways
        cause = " ".join(said.getvalue().split()) or f"{type(exc).__name__}: {exc}"
        raise MeshFileError(
            f"cannot read mesh file {str(path)!r} (empty, truncated, corrupt or a format meshio"
            f" does not read?): {cause}"
        ) from None


class _Ended(io.BufferedReader):
    """A file whose ``read(n)`` past its end raises meshio's ReadError (``readline`` still
    returns b"" there, as a reader's end-of-file test expects)."""

    def read(self, size: int | None = -1) -> bytes:
        data = super().read(size)
        if size and size > 0 and not data:
            raise meshio.ReadError("the file ends inside a bracketed section")
        return data


def _read_msh(path: str | os.PathLike) -> meshio.Mesh:
    """A .msh file as Fluent's format (meshio's own .msh), else as Gmsh's; one MeshFileError."""
    said = io.StringIO()
    causes = []
    for reader in (meshio.ansys.read, meshio.gmsh.read):
        try:
            with contextlib.redirect_stdout(said), contextlib.redirect_stderr(said):
                if reader is not meshio.ansys.read:
                    return reader(path)
                with _Ended(io.FileIO(path, "rb")) as source:
                    return reader(source)
        except (Exception, SystemExit) as exc:  # meshio signals malformed input many ways
            causes.append(" ".join(said.getvalue().split()) or f"{type(exc).__name__}: {exc}")
    raise MeshFileError(
        f"cannot read mesh file {str(path)!r} as ANSYS Fluent's or Gmsh's .msh (empty,"
        f" truncated or corrupt?): {'; '.join(c for c in causes if c)}"
    )


def load_mesh(path: str | os.PathLike[str]) -> TetMesh:
    """Read the tetrahedra of a mesh file into a validated `TetMesh`.

    Only the linear 'tetra' cell blocks are kept (files often also hold vertex, line and
    triangle blocks); nodes that no tetrahedron uses are dropped and negatively oriented
    tetrahedra are flipped, since conventions differ between tools.

    Raises:
        MeshFileError: the file is missing, unreadable, malformed or holds no tetrahedra.
        MeshError: the tetrahedra do not form a usable mesh (see `validate_mesh`).
    """
    path = Path(path)
    if not path.is_file():
        raise MeshFileError(f"mesh file {str(path)!r} does not exist")
    raw = read_meshio(path)

    blocks = [block.data for block in raw.cells if block.type == "tetra"]
    if not blocks or sum(len(b) for b in blocks) == 0:
        found = sorted({block.type for block in raw.cells}) or ["no cells"]
        raise MeshFileError(
            f"mesh file {str(path)!r} holds no linear tetrahedra ('tetra' cells); found: "
            f"{', '.join(found)}"
        )
    points = np.asarray(raw.points, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] != 3:
        raise MeshFileError(
            f"mesh file {str(path)!r} has points of shape {points.shape}, expected (n, 3)"
        )
    tets = np.concatenate(blocks).astype(np.int64)
    if tets.ndim != 2 or tets.shape[1] != 4 or tets.min() < 0 or tets.max() >= len(points):
        raise MeshFileError(
            f"mesh file {str(path)!r} has tetrahedra that name nodes it does not hold"
            f" ({len(points)} nodes, indices {tets.min()} to {tets.max()}): corrupt?"
        )
    points, tets = remove_unused_nodes(points, tets)
    tets = fix_orientation(points, tets)
    validate_mesh(points, tets)
    return TetMesh(points=points, tets=tets)


def save_mesh(mesh: TetMesh, path: str | os.PathLike[str]) -> None:
    """Write the nodes and tetrahedra of `mesh`; the format follows the file extension.

    The file is written next to its destination and moved into place, so that a reader never
    sees a half-written mesh. Surfaces and landmarks are not written.

    Raises:
        MeshFileError: the format is unknown or the file cannot be written.
    """
    path = Path(path)
    out = meshio.Mesh(points=mesh.points, cells=[("tetra", mesh.tets)])
    try:
        fd, tmp_name = tempfile.mkstemp(
            prefix=f".{path.name}.", suffix=path.suffix, dir=path.parent
        )
    except OSError as exc:
        raise MeshFileError(f"cannot write mesh file {str(path)!r}: {exc}") from exc
    os.close(fd)
    try:
        meshio.write(tmp_name, out)
        replace(tmp_name, path)
    except Exception as exc:  # unknown extension (ValueError), I/O failures (OSError), ...
        Path(tmp_name).unlink(missing_ok=True)
        raise MeshFileError(f"cannot write mesh file {str(path)!r}: {exc}") from exc
