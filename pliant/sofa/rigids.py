"""Rigid bodies of a SOFA scene, read into Pliant's (:class:`pliant.fem.rigid.RigidBody`).

A moving rigid body is a ``Rigid3`` MechanicalObject (its frame: the centre of mass) with a
``UniformMass``, whose collision model is

* a ``SphereCollisionModel`` on the frame's node (one sphere centred on the frame), or on a
  child carried by a ``RigidMapping`` whose one point is the frame's origin: a
  :class:`~pliant.geometry.collision.Sphere` of its ``radius``;
* points, lines or triangles of a child carried by a ``RigidMapping``: a
  :class:`~pliant.geometry.collision.Box` when they are a box's eight corners centred on the
  frame (exact box contacts), else a :class:`~pliant.geometry.collision.TriangleMesh` of the
  child's triangles when they close a surface, else of the points' convex hull (Pliant's
  collision has no open mesh: a rigid body's shape bounds a solid).

A ``Vec3`` MechanicalObject of one point with a ``SphereCollisionModel`` and a mass (SOFA's
particle ball, as in the Tripod tutorial's and SofaGym's mazes) is a rigid sphere too. SOFA
does not turn a particle; Pliant's rigid body turns, so its inertia is
:data:`PARTICLE_INERTIA` times a solid ball's: it slides as SOFA's does, spinning a negligible
amount under friction.

The mass is the ``UniformMass``: ``vertexMass`` as SOFA's rigid mass (mass, volume, and the
3x3 inertia per unit mass), or one number (the mass), or ``totalMass``; SOFA's rigid mass then
keeps its default inertia per unit mass, the identity. ``vertexMass="@mass.rigidMass"`` links
to a ``GenerateRigidMass``: the mass, volume and inertia of the solid its mesh bounds at its
``density`` (:func:`pliant.geometry.inertia.mesh_mass`), and ``centerToOrigin``, the shift that
puts the mesh's centre of mass on the frame (SofaGym's ``addRigidObject`` translates its
collision mesh by it).

A static rigid object (STLIB's ``isAStaticObject``: its collision models neither ``moving``
nor ``simulated``) is an obstacle: a sphere of the same radius, or the mesh.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from pliant.errors import ContactError, ModelError
from pliant.fem.rigid import RigidBody
from pliant.geometry.collision import Box, Shape, Sphere, TriangleMesh
from pliant.geometry.inertia import mesh_mass, sphere_inertia
from pliant.sofa.tree import SceneError, SceneNode, SceneObject, data_value, field_numbers

if TYPE_CHECKING:
    from pliant.sofa.loader import _Builder

SPHERE_MODEL = "SphereCollisionModel"
MASS_GENERATOR = "GenerateRigidMass"
MESH_MODELS = frozenset({"PointCollisionModel", "LineCollisionModel", "TriangleCollisionModel"})
# A particle ball's inertia over a solid ball's: SOFA's Vec3 particle does not turn.
PARTICLE_INERTIA = 1e6
# SOFA's GenerateRigidMass density when the scene gives none.
DEFAULT_DENSITY = 1000.0


def _is_link(value) -> bool:
    return isinstance(value, str) and value.strip().startswith("@")


def _template(dofs: SceneObject) -> str:
    return str(dofs.attrs.get("template", "Vec3"))


def sphere_radius(model: SceneObject) -> float:
    """A SphereCollisionModel's radius (``radius``, or its ``listRadius`` of one value)."""
    radii = field_numbers(model, "listRadius", []) if model.attrs.get("listRadius") else []
    if len(radii) > 1:
        raise SceneError(f"{model.path}.listRadius: one sphere per rigid body in Pliant")
    radius = radii[0] if len(radii) else field_numbers(model, "radius", 1.0)[0]
    if not (np.isfinite(radius) and radius > 0.0):
        raise SceneError(f"{model.path}.radius: a positive radius expected, got {radius!r}")
    return float(radius)


def is_particle_sphere(node: SceneNode) -> bool:
    """A node whose Vec3 MechanicalObject carries a SphereCollisionModel (a particle ball)."""
    dofs = [o for o in node.objects if o.type == "MechanicalObject"]
    return (
        len(dofs) == 1
        and _template(dofs[0]).startswith("Vec3")
        and any(o.type == SPHERE_MODEL for o in node.objects)
        and not any(o.type.endswith("Mapping") for o in node.objects)
    )


def particle_moves(node: SceneNode) -> bool:
    """A particle ball moves when its model moves, it has a mass and an ODE solver in its
    context (its node or an ancestor's); else SOFA leaves it where it is (a goal marker): an
    obstacle."""
    model = next(o for o in node.objects if o.type == SPHERE_MODEL)
    value = model.attrs.get("moving", True)
    moving = value.strip().lower() in ("1", "true") if isinstance(value, str) else bool(value)
    solver, at = False, node
    while at is not None and not solver:
        solver = any(o.type in ("EulerImplicitSolver", "StaticSolver") for o in at.objects)
        at = at.parent
    return moving and solver and any(o.type == "UniformMass" for o in node.objects)


def _mapped_children(node: SceneNode) -> list[SceneNode]:
    """The children carried rigidly that hold collision models."""
    return [
        c
        for c in node.children
        if any(o.type == "RigidMapping" for o in c.objects)
        and any(o.type in MESH_MODELS or o.type == SPHERE_MODEL for o in c.objects)
    ]


def _box(points: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """Half extents and centre when the points are an axis-aligned box's eight corners."""
    lo, hi = points.min(axis=0), points.max(axis=0)
    corners = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)])
    box = lo + corners * (hi - lo)
    if len(points) != 8 or not all(np.isclose(box, p).all(1).any() for p in points):
        return None
    return 0.5 * (hi - lo), 0.5 * (hi + lo)


def _faces(builder: _Builder, node: SceneNode, loaders: frozenset[str]) -> np.ndarray | None:
    """The triangles of a collision node: its topology's, else its loader's."""
    topology = builder._one(node, {"MeshTopology", "TriangleSetTopologyContainer"}, "topologies")
    triangles = None if topology is None else topology.attrs.get("triangles")
    if triangles is not None and not _is_link(triangles):
        return field_numbers(topology, "triangles", []).astype(np.int64).reshape(-1, 3)
    found = [o for o in node.objects if o.type in loaders]
    if len(found) != 1:
        return None
    return builder._loaded(found[0])[1].get("triangle")


def mesh_shape(points: np.ndarray, faces: np.ndarray | None, where: str) -> TriangleMesh:
    """The closed mesh of the triangles when they close a surface, else the points' convex
    hull (faces turned outwards)."""
    if faces is not None and len(faces) >= 4:
        try:
            return TriangleMesh(points, faces)
        except ContactError:
            pass
    try:
        hull = ConvexHull(points)
    except (QhullError, ValueError) as exc:
        raise SceneError(f"{where}: the collision points bound no solid ({exc})") from exc
    faces = hull.simplices.copy()
    tri = hull.points[faces]
    outward = np.einsum(
        "ij,ij->i",
        np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]),
        tri.mean(axis=1) - hull.points[hull.vertices].mean(axis=0),
    )
    faces[outward < 0] = faces[outward < 0][:, ::-1]
    used, faces = np.unique(faces, return_inverse=True)
    return TriangleMesh(hull.points[used], faces.reshape(-1, 3))


def rigid_shape(builder: _Builder, node: SceneNode) -> Shape:
    """The collision shape of a rigid body's node, in its frame."""
    own = [o for o in node.objects if o.type == SPHERE_MODEL]
    if own:
        return Sphere(sphere_radius(own[0]))
    children = _mapped_children(node)
    if len(children) != 1:
        raise SceneError(
            f"{node.path}: a rigid body collides through one child carried by a RigidMapping"
            f" (got {len(children)})"
        )
    child = children[0]
    dofs = builder._one(child, {"MechanicalObject"}, "MechanicalObjects")
    if dofs is None:
        raise SceneError(f"{child.path}: no MechanicalObject for the collision model")
    points = builder._positions(child, dofs)
    spheres = [o for o in child.objects if o.type == SPHERE_MODEL]
    if spheres:
        radius = sphere_radius(spheres[0])
        if len(points) != 1 or np.linalg.norm(points[0]) > 1e-9 * radius:
            raise SceneError(
                f"{child.path}: a rigid sphere is one point at its frame's origin (the centre of"
                f" mass), got {len(points)} points"
            )
        return Sphere(radius)
    box = _box(points)
    if box is not None:
        half, centre = box
        # within the corners' own tolerance (a mesh file's printed digits: SOFA's cube.obj
        # has corners at 0.999999 and 1.000001)
        if np.linalg.norm(centre) > 1e-5 * np.linalg.norm(half):
            raise SceneError(f"{child.path}: the box must be centred on the rigid frame")
        return Box(half)
    return mesh_shape(points, _faces(builder, child, builder.loaders), child.path)


def _rigid_mass_values(builder: _Builder, mass: SceneObject) -> np.ndarray:
    """SOFA's rigid mass of a UniformMass: (mass, volume, inertia per unit mass (9))."""
    link = mass.attrs.get("vertexMass")
    if _is_link(link):
        source = builder.link(mass.node, link)
        if source is None or source.type != MASS_GENERATOR:
            raise SceneError(f"{mass.path}.vertexMass: {link!r} names no GenerateRigidMass")
        generate_rigid_mass(builder, source)
        values = field_numbers(source, "rigidMass", [])
    elif link is None:
        values = field_numbers(mass, "totalMass", 1.0)
    else:
        values = field_numbers(mass, "vertexMass", 1.0)
    if values.size == 1:  # SOFA's rigid mass: volume 1 and the identity per unit mass
        values = np.concatenate([values, [1.0], np.eye(3).ravel()])
    if values.size != 11:
        raise SceneError(
            f"{mass.path}.vertexMass: mass, volume and a 3x3 inertia per unit mass expected"
        )
    return values


def rigid_body(builder: _Builder, node: SceneNode, friction: float) -> RigidBody:
    """A moving rigid body: a Rigid3 frame with its mass and collision shape, or a particle
    ball."""
    mass = builder._one(node, {"UniformMass"}, "masses")
    if mass is None:
        raise SceneError(f"{node.path}: a rigid body needs a mass (a UniformMass)")
    if is_particle_sphere(node):
        dofs = builder._one(node, {"MechanicalObject"}, "MechanicalObjects")
        points = builder._positions(node, dofs)
        if len(points) != 1:
            raise SceneError(f"{dofs.path}: one particle ball per node, got {len(points)}")
        radius = sphere_radius(next(o for o in node.objects if o.type == SPHERE_MODEL))
        key = "totalMass" if "totalMass" in mass.attrs else "vertexMass"
        m = float(field_numbers(mass, key, 1.0)[0])
        shape, position, rotation = Sphere(radius), points[0], np.eye(3)
        inertia = PARTICLE_INERTIA * sphere_inertia(m, radius)
    else:
        values = _rigid_mass_values(builder, mass)
        dofs = builder._one(node, {"MechanicalObject"}, "MechanicalObjects")
        position, rotation = builder._pose(dofs)
        shape, m = rigid_shape(builder, node), float(values[0])
        inertia = m * values[2:].reshape(3, 3)
    shape.set_pose(position, rotation)
    try:
        return RigidBody(
            shape, m, inertia, friction=friction, name=node.name, held=_held(node, dofs)
        )
    except ModelError as exc:
        raise SceneError(f"{node.path}: {exc}") from exc


def _held(node: SceneNode, dofs: SceneObject) -> np.ndarray | None:
    """The twist components a PartialFixedConstraint on the body's node holds (its
    ``fixedDirections``: x y z, then rx ry rz on a Rigid3 frame, world axes), or None."""
    held = np.zeros(6, dtype=bool)
    for obj in node.objects:
        if obj.type not in ("PartialFixedConstraint", "PartialFixedProjectiveConstraint"):
            continue
        indices = field_numbers(obj, "indices", [0])
        fix_all = str(obj.attrs.get("fixAll", False)).strip().lower() in ("1", "true", "yes")
        if not fix_all and 0 not in indices:
            continue  # it holds another frame: the body has one
        directions = field_numbers(obj, "fixedDirections", [1, 1, 1]) != 0
        size = 6 if _template(dofs).startswith("Rigid3") else 3
        if directions.size != size:
            raise SceneError(
                f"{obj.path}.fixedDirections: {size} flags for a {_template(dofs)} frame,"
                f" got {directions.size}"
            )
        held[:size] |= directions
    if held.all():
        raise SceneError(f"{node.path}: every motion held by a PartialFixedConstraint")
    return held if held.any() else None


def static_sphere(builder: _Builder, node: SceneNode) -> Sphere:
    """A still SphereCollisionModel (a static ball): a sphere obstacle where its one point is
    (its Rigid3 frame's origin, or the point carried by a RigidMapping from one)."""
    model = next(o for o in node.objects if o.type == SPHERE_MODEL)
    dofs = builder._one(node, {"MechanicalObject"}, "MechanicalObjects")
    if dofs is None:
        raise SceneError(f"{node.path}: no MechanicalObject for the sphere")
    if _template(dofs).startswith("Rigid3"):
        centre = builder._pose(dofs)[0][None]
    else:
        centre = builder._positions(node, dofs)
        frame = builder._rigid_dofs(node.parent)
        if frame is not None and any(o.type == "RigidMapping" for o in node.objects):
            position, rotation = builder._pose(frame)
            centre = centre @ rotation.T + position
    if len(centre) != 1:
        raise SceneError(f"{node.path}: one sphere per collision model, got {len(centre)}")
    return Sphere(sphere_radius(model), position=centre[0])


def generate_rigid_mass(builder: _Builder, obj: SceneObject) -> None:
    """GenerateRigidMass.init(): the rigid mass of the solid its mesh (``position`` and
    ``triangles``, or those of the loader ``src`` names) bounds at its ``density``: it sets
    ``mass``, ``volume``, ``inertiaMatrix`` (about the centre of mass), ``massCenter``,
    ``centerToOrigin`` (minus the centre) and ``rigidMass`` (mass, volume, and the inertia per
    unit mass, as a UniformMass's ``vertexMass``)."""
    if "rigidMass" in obj.attrs and not _is_link(obj.attrs["rigidMass"]):
        return
    points = obj.attrs.get("position")
    faces = obj.attrs.get("triangles")
    src = obj.attrs.get("src")
    if (points is None or faces is None) and _is_link(src):
        loader = builder.link(obj.node, src)
        if loader is None or loader.type not in builder.loaders:
            raise SceneError(f"{obj.path}.src: {src!r} names no mesh loader")
        points, cells = builder._loaded(loader)
        faces = cells.get("triangle")
    if points is None or faces is None or _is_link(points) or _is_link(faces):
        raise SceneError(f"{obj.path}: a mesh (position and triangles, or src) is needed")
    points = np.asarray(data_value(points), dtype=float).reshape(-1, 3)
    points = points * field_numbers(obj, "scale3d", [1.0, 1.0, 1.0])
    faces = np.asarray(data_value(faces), dtype=float).astype(np.int64).reshape(-1, 3)
    density = float(field_numbers(obj, "density", DEFAULT_DENSITY)[0])
    try:
        solid = mesh_mass(points, faces, density)
    except ModelError as exc:
        raise SceneError(f"{obj.path}: {exc}") from exc
    per_mass = solid.inertia / solid.mass
    obj.attrs.update(
        mass=solid.mass,
        volume=solid.volume,
        inertiaMatrix=solid.inertia.ravel().tolist(),
        massCenter=solid.centre.tolist(),
        centerToOrigin=(-solid.centre).tolist(),
        rigidMass=[solid.mass, solid.volume, *per_mass.ravel().tolist()],
    )
