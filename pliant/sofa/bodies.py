"""Several deformable bodies of a SOFA scene as one Pliant body.

A Pliant model has one deformable body; a SOFA scene may hold several (a gripper's fingers, two
objects side by side), each a node with its own FEM, mass, ODE solver and held nodes. Where
nothing couples them but the time step, they are one :class:`pliant.fem.body.TetBody` over the
disjoint union of their meshes: body k's nodes are the union's ``offsets[k]`` onwards, its
elements keep their Lame parameters (``mu``, ``lam`` per element), its nodes their masses
(:meth:`~pliant.fem.body.TetBody.set_node_masses`: each body's UniformMass spread over its
own nodes), its held DoFs, loads and projections move to the union's numbering. The union's
stiffness and mass matrices are block diagonal, one block per body, so a step moves each body
exactly as it would move alone (what the tests check), while the actuators, effectors and
contacts of all bodies are solved together, as SOFA's constraint solver does.

What stops such a scene, with one SceneError naming it:

- two bodies whose collision models SOFA tests against each other (no ``group`` in common)
  other than by points of one against triangles of the other: Pliant's contact between
  deformable bodies (:class:`pliant.constraints.surface.SurfaceContact`, built by
  :func:`surface_pairs`) is a point-triangle proximity, as SOFA's on the usual collision meshes
  (Point, Line and Triangle models together; the lines' contacts are not made);
- bodies whose elements follow different laws (a corotational and a hyperelastic one, or two
  element rotations): the union's elements share one kernel;
- different ODE solvers (static and dynamic), or consistent mass matrices of different
  densities: one solver steps the union (different Rayleigh damping joins: each part keeps its
  own, :meth:`pliant.fem.body.TetBody.set_rayleigh_per_body`);
- hexahedral bodies, and STLIB's Rigidify or UnilateralPlaneConstraint on one of several
  bodies (not joined here).
"""

from __future__ import annotations

import copy
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from pliant.constraints.base import EmbeddedPoints
from pliant.fem.body import TetBody
from pliant.fem.shell import ShellBody, TriangleFEM
from pliant.mesh.tetmesh import TetMesh
from pliant.sofa.tree import SceneError, SceneNode, SceneObject


@dataclass
class Part:
    """One of the scene's deformable bodies: its node, its body built alone, its mesh, its
    solver kind, and where its nodes start in the union."""

    node: SceneNode
    body: TetBody
    mesh: TetMesh
    solver_kind: str
    offset: int = 0

    @property
    def label(self) -> str:
        """The body's node path below the root: what its actuators' names begin with."""
        return self.node.path.partition("/")[2] or self.node.path

    def owns(self, node: SceneNode) -> bool:
        """Whether `node` is the body's node or under it."""
        at: SceneNode | None = node
        while at is not None:
            if at is self.node:
                return True
            at = at.parent
        return False

    def shifted(self, points: EmbeddedPoints) -> EmbeddedPoints:
        """Points embedded in this body's own mesh, read through the union's nodes."""
        out = copy.copy(points)
        out.nodes = points.nodes + self.offset
        return out


def _groups(model) -> frozenset[str]:
    value = model.attrs.get("group", "")
    if isinstance(value, str):
        return frozenset(value.replace(",", " ").split())
    values = value if isinstance(value, (list, tuple, np.ndarray)) else [value]
    return frozenset(str(int(v)) if float(v) == int(v) else str(v) for v in values)


POINTS, TRIANGLES = "PointCollisionModel", "TriangleCollisionModel"


def _models(node: SceneNode, collision_types: frozenset[str]) -> list[SceneObject]:
    return [o for n in node.walk() for o in n.objects if o.type in collision_types]


def surface_pairs(
    models: Sequence[tuple[int, SceneObject]],
) -> list[tuple[SceneObject, SceneObject]]:
    """(points, triangles) collision models that SOFA tests against each other among the
    `models` of the deformable bodies, each given with its body's number: a
    PointCollisionModel of one body and a TriangleCollisionModel of another with no ``group``
    in common, both ways."""
    return [
        (a, b)
        for i, a in models
        for j, b in models
        if i != j and a.type == POINTS and b.type == TRIANGLES and not (_groups(a) & _groups(b))
    ]


def touching_bodies(
    nodes: Sequence[SceneNode], collision_types: frozenset[str], *, unmet: bool = False
) -> list[str]:
    """Pairs of the deformable bodies under `nodes` that SOFA's collision pipeline tests
    against each other: a collision model of one and one of the other with no ``group`` in
    common (SOFA's CollisionModel::canCollideWith). With `unmet`, only those that do not
    touch by points of one against triangles of the other (:func:`surface_pairs`). Call it
    only where the scene detects collisions."""
    models = [_models(node, collision_types) for node in nodes]
    found = []
    for i in range(len(nodes)):
        for j in range(i + 1, len(nodes)):
            pair = next(
                ((a, b) for a in models[i] for b in models[j] if not (_groups(a) & _groups(b))),
                None,
            )
            both = [(0, m) for m in models[i]] + [(1, m) for m in models[j]]
            if pair is None or (unmet and surface_pairs(both)):
                continue
            found.append(
                f"{nodes[i].path} and {nodes[j].path} (through {pair[0].node.path} and"
                f" {pair[1].node.path})"
            )
    return found


def contact_problem(nodes: Sequence[SceneNode], collision_types: frozenset[str]) -> str | None:
    """The error's words for deformable bodies that SOFA makes touch otherwise than by points
    of one against triangles of the other (Pliant's SurfaceContact), or None."""
    pairs = touching_bodies(nodes, collision_types, unmet=True)
    if not pairs:
        return None
    return (
        "contact between deformable bodies, which SOFA tests: "
        + "; ".join(pairs)
        + " (collision models with no group in common), not by points of one against triangles"
        " of the other (a PointCollisionModel and a TriangleCollisionModel), the only contact"
        " between deformable bodies Pliant has"
    )


def _shifted_copy(item, name: str, offset: int):
    out = copy.copy(item)
    setattr(out, name, getattr(item, name) + offset)
    return out


def _check_alike(parts: Sequence[Part], scene: str) -> None:
    """SceneError naming what differs between the bodies where one body cannot hold them."""
    problems = []
    for part in parts:
        if type(part.body) is not TetBody and not isinstance(part.body, ShellBody):
            problems.append(
                f"{part.node.path} is not a body of tetrahedra or triangles (only those join)"
            )
        if part.body.membranes:
            problems.append(f"{part.node.path} has membranes")
        damped = {p.body.rayleigh_stiffness for p in parts}
        if isinstance(part.body, ShellBody) and part.body.rayleigh_stiffness and len(damped) > 1:
            problems.append(
                f"{part.node.path}: a shell of triangles damped by its stiffness"
                " (rayleighStiffness) beside bodies damped otherwise"
            )
    solids = [p for p in parts if not isinstance(p.body, ShellBody)]
    if not solids:
        problems.append("shells of triangles only (one joins beside bodies of tetrahedra)")
    kinds = {p.solver_kind for p in parts}
    if len(kinds) > 1:
        problems.append(
            "static and dynamic ODE solvers ("
            + ", ".join(f"{p.node.path}: {p.solver_kind}" for p in parts)
            + ")"
        )
    laws = {
        (type(m).__name__, m.kernel_tag, m.tolerates_inversion)
        for m in (p.body.material for p in solids)
    }
    if len(laws) > 1:
        problems.append(
            "elements of different laws ("
            + ", ".join(f"{p.node.path}: {p.body.material!r}" for p in solids)
            + "): the elements of one Pliant body share one law and element rotation"
        )
    massless = [p for p in parts if p.body.massless]
    if massless and len(massless) < len(parts):
        problems.append(
            "a body with no mass beside bodies with one"
            f" ({', '.join(f'{p.node.path}: {p.body.mass_type}' for p in parts)})"
        )
    consistent = [p for p in parts if p.body.mass_type == "consistent"]
    if consistent and (len(consistent) < len(parts) or len({p.body.density for p in parts}) > 1):
        problems.append(
            "a consistent mass matrix (MeshMatrixMass) beside another mass or density"
            f" ({', '.join(f'{p.node.path}: {p.body.mass_type}' for p in parts)})"
        )
    if problems:
        raise SceneError(
            f"{scene}: its deformable bodies ({', '.join(p.node.path for p in parts)}) cannot be"
            " joined in one Pliant body: " + "; ".join(problems)
        )


def check_held_if_massless(node: SceneNode, body: TetBody) -> None:
    """SceneError for a body with no mass that nothing holds against a rigid motion: SOFA's
    implicit step is then the stiffness alone, singular (an iterative solver leaves the body
    still only while no force acts on it)."""
    free = body.free_rigid_motions() if body.massless else []
    if free:
        raise SceneError(
            f"{node.path}: the body has no mass (UniformMass, MeshMatrixMass) and nothing holds"
            f" it ({'; '.join(free)} free): its step, the stiffness alone, is singular"
        )


def join(parts: Sequence[Part], scene: str) -> TetBody:
    """One body over the disjoint union of the parts' meshes (each built alone, their
    offsets set here), with each part's elements, masses, held DoFs, loads and projections.
    SceneError, naming the `scene`, where they differ in what one body shares (see the module
    text)."""
    _check_alike(parts, scene)
    offset = 0
    for part in parts:
        part.offset = offset
        offset += part.body.n_nodes
    bodies = [p.body for p in parts]
    solids = [p for p in parts if not isinstance(p.body, ShellBody)]
    first = solids[0].body
    points = np.vstack([b.rest_positions for b in bodies])
    tets = np.vstack([p.body.tets + p.offset for p in solids])
    large = first.frame_nodes.shape[0] > 0
    frames = np.vstack([p.body.frame_nodes + p.offset for p in solids])
    # A shell's triangles act on the union's nodes as a membrane does (pliant.fem.shell).
    shells = [
        TriangleFEM(points, p.body.triangles + p.offset, p.body.material)
        for p in parts
        if isinstance(p.body, ShellBody)
    ]
    held = np.concatenate([np.flatnonzero(p.body.free_index < 0) + 3 * p.offset for p in parts])
    loads = [_shifted_copy(a.load, "groups", p.offset) for p in parts for a in p.body.loads]
    projections = [_shifted_copy(j, "nodes", p.offset) for p in parts for j in p.body.projections]
    if first.mass_type == "consistent":
        mass = {"mass": "consistent", "density": first.density}
    elif first.massless:
        mass = {"mass": "none"}
    else:
        mass = {
            "mass": "uniform" if all(b.mass_type == "uniform" for b in bodies) else "lumped",
            "total_mass": float(sum(b.total_mass for b in bodies)),
        }
    body = TetBody(
        TetMesh(points, tets),
        first.material,
        separate=True,
        fixed_dofs=held,
        frame_nodes=frames if large else None,
        membranes=shells,
        loads=loads,
        projections=projections,
        gravity=tuple(first.gravity),
        rayleigh_mass=first.rayleigh_mass,
        rayleigh_stiffness=first.rayleigh_stiffness,
        **mass,
    )
    body.mu[:] = np.concatenate([p.body.mu for p in solids])
    body.lam[:] = np.concatenate([p.body.lam for p in solids])
    if body.mass_type not in ("consistent", "none"):
        body.set_node_masses(np.concatenate([b.node_masses for b in bodies]))
    # Each part damped as under its own solver (one pair for all keeps the scalar path).
    body.set_rayleigh_per_body(
        np.concatenate([np.full(b.n_nodes, b.rayleigh_mass) for b in bodies]),
        np.concatenate([np.full(p.body.n_elements, p.body.rayleigh_stiffness) for p in solids]),
    )
    body.changed()
    return body
