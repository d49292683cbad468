"""SofaGym's shared scene helpers (``sofagym.header``, ``sofagym.utils``) that its
environments' scenes import, written for Pliant from what they are documented to add.

``addHeader`` sets up the root as SofaGym's scenes expect (frictional contact pipeline,
constraint-based loop, animation manager, gravity and time step); ``addVisu`` adds cameras and
lights only, which Pliant does not draw. ``addRigidObject`` adds a rigid body given by a mesh
and a density (read by :mod:`pliant.sofa.rigids`). The beam builders of ``sofagym.utils`` need
a model Pliant lacks (Cosserat rods): they stop the load with a :class:`SceneError` naming it.
"""

from __future__ import annotations

import numpy as np

from pliant.sofa.prefabs.splib import AnimationManager
from pliant.sofa.prefabs.stlib import SHAPES, ContactHeader
from pliant.sofa.tree import SceneError, SceneNode


def addHeader(  # noqa: N802 (SofaGym's names)
    rootNode: SceneNode,  # noqa: N803
    alarmDistance: float = 2.0,  # noqa: N803
    contactDistance: float = 0.5,  # noqa: N803
    tolerance: float = 1e-6,
    maxIterations: int = 500,  # noqa: N803
    gravity=(0.0, -981.0, 0.0),
    dt: float = 0.03,
    mu: str | float = "0.8",
    genericConstraintSolver: bool = True,  # noqa: N803
) -> None:
    """The root of a SofaGym scene: the contact pipeline with friction `mu` and the given
    distances, the constraint-based animation loop (with SOFA's constraint solver, which
    Pliant replaces by its exact one), the animation manager, gravity and time step."""
    ContactHeader(rootNode, alarmDistance, contactDistance, frictionCoef=float(mu))
    if genericConstraintSolver:
        rootNode.addObject(
            "GenericConstraintSolver", tolerance=tolerance, maxIterations=maxIterations
        )
    AnimationManager(rootNode)
    rootNode.gravity = list(gravity)
    rootNode.dt = dt


def addVisu(rootNode: SceneNode, config, position, direction, cutoff: float = 250.0) -> None:  # noqa: N802, N803
    """Cameras and spot lights: nothing Pliant simulates."""


# SOFA's shared meshes a scene may name (SofaGym's carts: mesh/cube.obj), written out.
_SHARED = {"mesh/cube.obj": SHAPES["cube"]}


def _mesh(node: SceneNode, filename: str, scale) -> dict:
    """The mesh of `filename` in `node` (a loader named ``loader``, or SOFA's shared mesh
    written out as a topology): the data a GenerateRigidMass reads it from."""
    scale3d = np.broadcast_to(np.asarray(scale, dtype=float), 3)
    shared = _SHARED.get(str(filename).replace("\\", "/"))
    if shared is None:
        loader = "MeshSTLLoader" if str(filename).lower().endswith(".stl") else "MeshOBJLoader"
        node.addObject(loader, name="loader", filename=filename, scale3d=scale3d.tolist())
        return {"src": "@" + node.name + "/loader"}
    points, faces = np.asarray(shared[0]) * scale3d, np.asarray(shared[1]).ravel().tolist()
    node.addObject("MeshTopology", name="loader", position=points.tolist(), triangles=faces)
    return {"position": points.tolist(), "triangles": faces}


def addRigidObject(  # noqa: N802
    node: SceneNode,
    filename: str,
    collisionFilename: str | None = None,  # noqa: N803
    position=(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0),
    scale=(1.0, 1.0, 1.0),
    textureFilename: str = "",  # noqa: N803
    color=(1.0, 1.0, 1.0),
    density: float = 0.002,
    name: str = "Object",
    withSolver: bool = True,  # noqa: N803
) -> SceneNode:
    """A rigid body given by a surface mesh (`filename`, scaled by `scale`) and a `density`,
    as SofaGym documents it: a child `name` of `node` with a Rigid3 MechanicalObject at
    `position` (x y z and a quaternion), a solver unless `withSolver` is false, a ``Visu``
    child (the mesh, drawn), a ``GenerateRigidMass`` named ``mass`` (the solid's mass and
    inertia at `density`) read by a UniformMass, and a ``Collision`` child: the collision mesh
    (`collisionFilename`, by default the same) shifted so that its centre of mass is on the
    frame, with triangle, line and point models, carried by a RigidMapping."""
    body = node.addChild(name)
    body.addObject("MechanicalObject", template="Rigid3", position=list(position))
    if withSolver:
        body.addObject("EulerImplicitSolver")
        body.addObject("CGLinearSolver", tolerance=1e-5, iterations=25, threshold=1e-5)
        body.addObject("UncoupledConstraintCorrection")
    visual = body.addChild("Visu")
    source = _mesh(visual, filename, scale)
    visual.addObject("OglModel", color=list(color) if not textureFilename else "")
    visual.addObject("RigidMapping")
    mass = body.addObject("GenerateRigidMass", name="mass", density=density, **source)
    mass.init()
    shift = list(mass.centerToOrigin.value)
    body.addObject("UniformMass", vertexMass="@mass.rigidMass")
    collision = body.addChild("Collision")
    given = _mesh(collision, collisionFilename or filename, scale)
    if "src" in given:
        collision.addObject("MeshTopology", src="@loader")
        collision.addObject("MechanicalObject", translation=shift)
    else:
        collision.addObject("MechanicalObject", position=given["position"], translation=shift)
    for model in ("TriangleCollisionModel", "LineCollisionModel", "PointCollisionModel"):
        collision.addObject(model)
    collision.addObject("RigidMapping")
    return body


def _lacks(what: str):
    def refuse(*_args, **_kwargs):
        raise SceneError(f"sofagym.utils.{what}: Pliant has no {_LACKS[what]}")

    refuse.__name__ = what
    return refuse


_LACKS = {
    "createCosserat": "Cosserat rod (SOFA's Cosserat plugin)",
    "addEdgeCollision": "collision model on a Cosserat rod's edges",
}


def header_members() -> dict:
    return {"addHeader": addHeader, "addVisu": addVisu}


def utils_members() -> dict:
    return {"addRigidObject": addRigidObject} | {name: _lacks(name) for name in _LACKS}
