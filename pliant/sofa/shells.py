"""Shells of SOFA scenes: a TriangleFEMForceField on a triangle topology.

* ``TriangleFEMForceField``: ``youngModulus`` (SOFA's default 1000), ``poissonRatio`` (0.3),
  ``thickness`` (1), ``method`` "large" (SOFA's default, corotational) or "small" (linear),
  :class:`pliant.fem.shell.ShellBody`. ``planeStrain`` (SOFA's plane-strain law) is refused.
* The triangles are the node's topology's (``MeshTopology`` or ``TriangleSetTopologyContainer``
  ``triangles``, numbers or a link to a loader's), else its loader's; the nodes are those of
  the node's MechanicalObject (its own scale, rotation and translation applied, as SOFA's
  MechanicalObject does at initialisation).
* The mass (UniformMass, MeshMatrixMass), held nodes, loads and the solver are read as for a
  tetrahedral body. A shell carries no mapped points (cables, effectors, collision points in a
  child node): it collides by its own nodes and triangles.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from pliant.errors import PliantError
from pliant.fem.shell import PlaneStress, ShellBody
from pliant.sofa.bodies import check_held_if_massless
from pliant.sofa.tree import SceneError, SceneNode, SceneObject, field_numbers

if TYPE_CHECKING:
    from pliant.sofa.loader import _Builder

TRIANGLE_FEM = "TriangleFEMForceField"
_TOPOLOGIES = ("MeshTopology", "TriangleSetTopologyContainer")
_METHODS = ("large", "small")


@dataclass(frozen=True)
class ShellMesh:
    """A shell's nodes and triangles (what the loader keeps of a body's mesh)."""

    points: np.ndarray
    triangles: np.ndarray

    @property
    def n_nodes(self) -> int:
        return int(self.points.shape[0])

    def boundary_triangles(self) -> np.ndarray:
        return self.triangles


def _number(fem: SceneObject, key: str, default: float) -> float:
    values = field_numbers(fem, key, default)
    return float(np.asarray(values, dtype=float).ravel()[0])


def _triangles(builder: _Builder, node: SceneNode) -> np.ndarray:
    """The node's triangles: its topology's ``triangles`` (numbers or a loader's), else its
    loader's."""
    topology = next((o for o in node.objects if o.type in _TOPOLOGIES), None)
    value = None if topology is None else topology.attrs.get("triangles")
    if value is not None and not (isinstance(value, str) and value.strip().startswith("@")):
        numbers = np.asarray(field_numbers(topology, "triangles", ()), dtype=float)
        if numbers.size == 0 or numbers.size % 3:
            raise SceneError(f"{topology.path}.triangles: triples of node indices expected")
        return numbers.astype(np.int64).reshape(-1, 3)
    loader = None
    if value is not None:
        loader = builder.link(node, str(value))
    if loader is None and topology is not None:
        src = topology.attrs.get("src")
        if isinstance(src, str) and src.strip().startswith("@"):
            loader = builder.link(node, src)
    if loader is None:
        loader = builder._mesh_loader(node)
    faces = builder._loaded(loader)[1].get("triangle")
    if faces is None or len(faces) == 0:
        raise SceneError(f"{node.path}: the shell's topology holds no triangles")
    return np.asarray(faces, dtype=np.int64).reshape(-1, 3)


def shell_body(
    builder: _Builder, node: SceneNode, fem: SceneObject, gravity: np.ndarray
) -> tuple[ShellBody, ShellMesh, str]:
    """The body of a TriangleFEMForceField node: its triangles, law, mass, held nodes, loads
    and solver."""
    method = str(fem.attrs.get("method", "large")).lower()
    if method not in _METHODS:
        raise SceneError(
            f"{fem.path}: method {method!r} is not supported for triangles ({', '.join(_METHODS)})"
        )
    if str(fem.attrs.get("planeStrain", "false")).lower() in ("1", "true"):
        raise SceneError(f"{fem.path}: planeStrain (SOFA's plane-strain triangle) is not supported")
    carried = [
        child.path
        for child in node.walk()
        if child is not node
        and any(
            o.type == "MechanicalObject" or o.type.endswith("CollisionModel") for o in child.objects
        )
    ]
    if carried:
        raise SceneError(
            f"{node.path}: points carried by a shell of triangles ({', '.join(carried)}) are not"
            " supported (a shell collides by its own nodes and triangles; cables, effectors and"
            " mapped collision meshes need a body of tetrahedra)"
        )
    dofs = builder._one(node, {"MechanicalObject"}, "MechanicalObjects")
    if dofs is None:
        raise SceneError(
            f"{node.path}: the shell has no MechanicalObject (a TriangleFEMForceField on the"
            " nodes of a body above it, a membrane layer, is not supported)"
        )
    points = builder._positions(node, dofs)
    triangles = _triangles(builder, node)
    if triangles.max() >= len(points):
        raise SceneError(f"{node.path}: triangles index {triangles.max()} of {len(points)} nodes")
    options, solver_kind = builder.body_options(node, points, gravity)
    try:
        material = PlaneStress(
            _number(fem, "youngModulus", 1000.0),
            _number(fem, "poissonRatio", 0.3),
            thickness=_number(fem, "thickness", 1.0),
            method=method,
        )
        body = ShellBody(points, triangles, material, **options)
    except PliantError as exc:
        raise SceneError(f"{fem.path}: {exc}") from exc
    check_held_if_massless(node, body)
    return body, ShellMesh(points, triangles), solver_kind
