"""Shells of SOFA scenes: a TriangleFEMForceField on a triangle topology.

* ``TriangleFEMForceField``: ``youngModulus`` (SOFA's default 1000), ``poissonRatio`` (0.3),
  ``thickness`` (1), ``method`` "large" (SOFA's default, corotational) or "small" (linear),
  :class:`pliant.fem.shell.ShellBody`. ``planeStrain`` (SOFA's plane-strain law) is refused.
* The triangles are the node's topology's (``MeshTopology`` or ``TriangleSetTopologyContainer``
  ``triangles``, numbers or a link to a loader's), else its loader's; the nodes are those of
  the node's MechanicalObject (its own scale, rotation and translation applied, as SOFA's
  MechanicalObject does at initialisation).
* A TriangleFEMForceField in a child node of a body of tetrahedra, with a triangle topology
  and no MechanicalObject, acts on the body's nodes (SOFA's context): a membrane
  (:func:`membrane`), e.g. the MultiGait's paper layer, whose triangles are given or a
  BoxROI's ``trianglesInROI`` (faces of the body's tetrahedra in its boxes).
* The mass (UniformMass, MeshMatrixMass), held nodes, loads and the solver are read as for a
  tetrahedral body. A shell carries no mapped points (cables, effectors, collision points in a
  child node): it collides by its own nodes and triangles.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from pliant.errors import PliantError
from pliant.fem.shell import PlaneStress, ShellBody, TriangleFEM
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


def plane_stress(fem: SceneObject) -> PlaneStress:
    """A TriangleFEMForceField's law (SOFA's defaults: E 1000, nu 0.3, thickness 1, "large")."""
    method = str(fem.attrs.get("method", "large")).lower()
    if method not in _METHODS:
        raise SceneError(
            f"{fem.path}: method {method!r} is not supported for triangles ({', '.join(_METHODS)})"
        )
    if str(fem.attrs.get("planeStrain", "false")).lower() in ("1", "true"):
        raise SceneError(f"{fem.path}: planeStrain (SOFA's plane-strain triangle) is not supported")
    try:
        return PlaneStress(
            _number(fem, "youngModulus", 1000.0),
            _number(fem, "poissonRatio", 0.3),
            thickness=_number(fem, "thickness", 1.0),
            method=method,
        )
    except PliantError as exc:
        raise SceneError(f"{fem.path}: {exc}") from exc


def shell_body(
    builder: _Builder, node: SceneNode, fem: SceneObject, gravity: np.ndarray
) -> tuple[ShellBody, ShellMesh, str]:
    """The body of a TriangleFEMForceField node: its triangles, law, mass, held nodes, loads
    and solver."""
    material = plane_stress(fem)
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
            " nodes of a body above it is a membrane on a body of tetrahedra only)"
        )
    points = builder._positions(node, dofs)
    triangles = _triangles(builder, node)
    if triangles.max() >= len(points):
        raise SceneError(f"{node.path}: triangles index {triangles.max()} of {len(points)} nodes")
    options, solver_kind = builder.body_options(node, points, gravity)
    try:
        body = ShellBody(points, triangles, material, **options)
    except PliantError as exc:
        raise SceneError(f"{fem.path}: {exc}") from exc
    check_held_if_massless(node, body)
    return body, ShellMesh(points, triangles), solver_kind


def is_membrane(node: SceneNode, fems: frozenset[str]) -> bool:
    """A TriangleFEMForceField on a body's nodes: a child of a node with another FEM (one of
    `fems`), with the triangle FEM and no MechanicalObject."""
    parent = node.parent
    return (
        parent is not None
        and any(o.type in fems and o.type != TRIANGLE_FEM for o in parent.objects)
        and any(o.type == TRIANGLE_FEM for o in node.objects)
        and not any(o.type == "MechanicalObject" for o in node.objects)
    )


def tet_faces(tets: np.ndarray) -> np.ndarray:
    """Every face of the tetrahedra once (boundary and interior), each as the first element
    that has it orders it (outward from that element)."""
    local = np.array([[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]])
    faces = np.asarray(tets)[:, local].reshape(-1, 3)
    _, first = np.unique(np.sort(faces, axis=1), axis=0, return_index=True)
    return faces[np.sort(first)]


def membrane(builder: _Builder, node: SceneNode, points: np.ndarray, tets: np.ndarray):
    """The membrane a :func:`is_membrane` node puts on its parent's body: TriangleFEM on the
    body's nodes (`points`), its triangles the node's topology's, numbers or a BoxROI's
    ``trianglesInROI`` (the faces of `tets` all of whose nodes are in one of its boxes; with
    ``strict`` false, whose centre is)."""
    fem = next(o for o in node.objects if o.type == TRIANGLE_FEM)
    topology = next((o for o in node.objects if o.type in _TOPOLOGIES), None)
    value = None if topology is None else topology.attrs.get("triangles")
    if value is None:
        raise SceneError(
            f"{node.path}: a membrane on the body's nodes needs a topology's triangles"
        )
    if isinstance(value, str) and value.strip().startswith("@"):
        box = builder.link(node, value)
        if box is None or box.type != "BoxROI" or not value.strip().endswith("trianglesInROI"):
            raise SceneError(f"{topology.path}.triangles: {value!r} is no BoxROI's trianglesInROI")
        faces = tet_faces(tets)
        if str(box.attrs.get("strict", "true")).lower() in ("0", "false"):
            chosen = np.zeros(len(faces), dtype=bool)
            chosen[builder._box_nodes(box, points[faces].mean(axis=1))] = True
        else:
            inside = np.zeros(len(points), dtype=bool)
            inside[builder._box_nodes(box, points)] = True
            chosen = inside[faces].all(axis=1)
        triangles = faces[chosen]
    else:
        numbers = np.asarray(field_numbers(topology, "triangles", ()), dtype=float)
        if numbers.size == 0 or numbers.size % 3:
            raise SceneError(f"{topology.path}.triangles: triples of node indices expected")
        triangles = numbers.astype(np.int64).reshape(-1, 3)
    if len(triangles) == 0:
        raise SceneError(f"{node.path}: the membrane holds no triangle")
    try:
        return TriangleFEM(points, triangles, plane_stress(fem))
    except PliantError as exc:
        raise SceneError(f"{fem.path}: {exc}") from exc
