"""A deterministic, self-cleaning gmsh session for the parametric shape builders."""

from __future__ import annotations

import functools
import signal
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import ParamSpec, TypeVar

import gmsh
import numpy as np

from pliant.errors import MeshingError
from pliant.mesh.quality import fix_orientation, remove_unused_nodes

# gmsh element type of the 4-node (linear) tetrahedron.
_TET4 = 4

# One thread and a fixed seed: gmsh's 3D Delaunay and its optimisers are deterministic only
# single-threaded, and the same parameters must give the same mesh.
_OPTIONS = {
    "General.Terminal": 0,
    "General.Verbosity": 0,
    "General.NumThreads": 1,
    "Mesh.MaxNumThreads1D": 1,
    "Mesh.MaxNumThreads2D": 1,
    "Mesh.MaxNumThreads3D": 1,
    "Mesh.RandomSeed": 1,
    "Mesh.Algorithm": 6,  # Frontal-Delaunay surfaces
    "Mesh.Algorithm3D": 1,  # Delaunay volumes
    "Mesh.ElementOrder": 1,
    "Mesh.Optimize": 1,
    "Mesh.OptimizeNetgen": 1,
    "Mesh.MeshSizeFromCurvature": 0,
    "Mesh.MeshSizeExtendFromBoundary": 1,
}
# Surface algorithms tried in turn when the 3-D Delaunay cannot recover the boundary of the
# first surface mesh (it happens at a few parametric designs): Delaunay, then MeshAdapt.
_FALLBACK_2D = (5, 1)
_overrides: dict[str, float] = {}
# Options a caller's own gmsh session gets back as they were.
_SAVED_OPTIONS = [*_OPTIONS, "Mesh.MeshSizeMax", "Mesh.MeshSizeMin"]


def _ignore_sigpipe() -> None:
    """Give SIGPIPE back to Python: gmsh's initialisation restores its default action (end the
    process), so a later write to a dead worker's pipe killed the process (exit 141) where
    Python raises BrokenPipeError. Only the main thread may set a handler."""
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGPIPE, signal.SIG_IGN)


@contextmanager
def gmsh_model(name: str) -> Iterator[None]:
    """Open an empty gmsh model with Pliant's meshing options; clean everything up afterwards.

    When the caller already runs gmsh, its session, current model and options are left as they
    were; otherwise gmsh is finalised on exit, also when meshing fails.
    """
    owns_session = not gmsh.isInitialized()
    if owns_session:
        # interruptible=False: no SIGINT handler, so this also works outside the main thread.
        gmsh.initialize(readConfigFiles=False, interruptible=False)
        _ignore_sigpipe()
        previous_model, saved_options = None, {}
    else:
        previous_model = gmsh.model.getCurrent()
        saved_options = {key: gmsh.option.getNumber(key) for key in _SAVED_OPTIONS}
    try:
        for key, value in {**_OPTIONS, **_overrides}.items():
            gmsh.option.setNumber(key, value)
        gmsh.model.add(name)
        yield
    finally:
        if owns_session:
            gmsh.finalize()
            _ignore_sigpipe()
        else:
            gmsh.model.remove()
            for key, value in saved_options.items():
                gmsh.option.setNumber(key, value)
            if previous_model:
                gmsh.model.setCurrent(previous_model)


P = ParamSpec("P")
R = TypeVar("R")


def retry_meshing(build: Callable[P, R]) -> Callable[P, R]:
    """Run a shape builder again with the fallback surface algorithms when meshing fails.

    The whole builder runs again in a new gmsh session: after a failed ``generate`` the same
    session meshed nothing more, not even the curves (measured; a busy lock left set is our
    reading), so retrying inside it cannot work.
    Deterministic: the same parameters take the same path to the same mesh.
    """

    @functools.wraps(build)
    def wrapper(*args: P.args, **kwargs: P.kwargs) -> R:
        try:
            return build(*args, **kwargs)
        except MeshingError as first:
            if not _owns_next_session():
                raise
            for algorithm in _FALLBACK_2D:
                _overrides["Mesh.Algorithm"] = algorithm
                try:
                    return build(*args, **kwargs)
                except MeshingError:
                    continue
                finally:
                    _overrides.clear()
            raise first

    return wrapper


def _owns_next_session() -> bool:
    """Whether the next :func:`gmsh_model` starts its own session (a caller's is kept)."""
    return not gmsh.isInitialized()


def mesh_volumes(mesh_size: float) -> tuple[np.ndarray, np.ndarray]:
    """Mesh the current model's volumes with linear tetrahedra of about `mesh_size`.

    Returns (n, 3) node coordinates and (m, 4) positively oriented node indices, with only the
    nodes that the tetrahedra use.
    """
    gmsh.model.occ.synchronize()
    gmsh.option.setNumber("Mesh.MeshSizeMax", mesh_size)
    gmsh.option.setNumber("Mesh.MeshSizeMin", 0.0)
    try:
        gmsh.model.mesh.generate(3)
    except Exception as exc:  # gmsh raises bare Exceptions
        raise MeshingError(f"gmsh could not mesh the volumes: {exc}") from exc
    node_tags, coords, _ = gmsh.model.mesh.getNodes()
    _, tet_nodes = gmsh.model.mesh.getElementsByType(_TET4)
    row_of_tag = np.full(int(node_tags.max()) + 1, -1, dtype=np.int64)
    row_of_tag[node_tags.astype(np.int64)] = np.arange(node_tags.size)
    points = np.asarray(coords, dtype=np.float64).reshape(-1, 3)
    tets = row_of_tag[np.asarray(tet_nodes, dtype=np.int64)].reshape(-1, 4)
    points, tets = remove_unused_nodes(points, tets)
    return points, fix_orientation(points, tets)
