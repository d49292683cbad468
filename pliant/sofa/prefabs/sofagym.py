"""SofaGym's shared scene helpers (``sofagym.header``, ``sofagym.utils``) that its
environments' scenes import, written for Pliant from what they are documented to add.

``addHeader`` sets up the root as SofaGym's scenes expect (frictional contact pipeline,
constraint-based loop, animation manager, gravity and time step); ``addVisu`` adds cameras and
lights only, which Pliant does not draw. ``addRigidObject`` adds a rigid body given by a mesh
and a density (read by :mod:`pliant.sofa.rigids`). ``createCosserat`` adds a Cosserat rod of
SOFA's Cosserat plugin and ``addEdgeCollision`` collision models on its frames (read by
:mod:`pliant.sofa.rods`); ``express_point`` gives a pose relative to another.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from pliant.sofa.prefabs.splib import AnimationManager
from pliant.sofa.prefabs.stlib import SHARED_MESHES, ContactHeader
from pliant.sofa.tree import SceneNode


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


def _mesh(node: SceneNode, filename: str, scale) -> dict:
    """The mesh of `filename` in `node` (a loader named ``loader``, or SOFA's shared mesh
    written out as a topology): the data a GenerateRigidMass reads it from."""
    scale3d = np.broadcast_to(np.asarray(scale, dtype=float), 3)
    shared = SHARED_MESHES.get(str(filename).replace("\\", "/"))
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


def addEdgeCollision(parentNode: SceneNode, position3D, edges) -> SceneNode:  # noqa: N802, N803
    """Collision lines and points on a rod's frames: a child ``CollisCosserat`` of
    `parentNode` (the frames' node) with an edge set on the points `position3D` (`edges`: the
    flat list of point pairs), a MechanicalObject ``CollisionDOFs`` on them, line and point
    models (group 2) and an IdentityMapping from the frames' positions."""
    node = parentNode.addChild("CollisCosserat")
    node.addObject("EdgeSetTopologyContainer", name="collisEdgeSet", position=position3D,
                   edges=edges)  # fmt: skip
    node.addObject("EdgeSetTopologyModifier", name="collisEdgeModifier")
    node.addObject("MechanicalObject", name="CollisionDOFs", position=position3D)
    node.addObject("LineCollisionModel", bothSide=1, group=2)
    node.addObject("PointCollisionModel", bothSide=1, group=2)
    node.addObject("IdentityMapping", name="mapping")
    return node


def createCosserat(  # noqa: N802
    parent: SceneNode,
    config: dict,
    name: str = "Cosserat",
    orientation=(0.0, 0.0, 0.0, 1.0),
    radius: float = 0.5,
    last_frame: dict | None = None,
    rigidBase: SceneNode | None = None,  # noqa: N803
    nonColored: bool = False,  # noqa: N803
    buildCollision: bool = False,  # noqa: N803
    youngModulus: float = 100e6,  # noqa: N803
) -> SceneNode:
    """A Cosserat rod of SOFA's Cosserat plugin as SofaGym documents its builder: a child
    `name` of `parent` with its solver (EulerImplicitSolver, Rayleigh 0.1 mass and 0.2
    stiffness), holding

    * the base: a child ``rigidBase`` with a Rigid3 MechanicalObject ``RigidBaseMO`` at
      ``config["init_pos"]`` and `orientation` (x y z w), held by springs (5000 on its
      position and its angle); or the node `rigidBase` given (a cart), made a child too;
    * ``rateAngularDeform``: the strains (torsion and two bendings per unit length, zero at
      rest) of ``config["nbSectionS"]`` sections of equal length along
      ``config["tot_length"]``, with a BeamHookeLawForceField (circular section of `radius`,
      `youngModulus`);
    * ``MappedFrames``, child of both: a Rigid3 MechanicalObject ``FramesMO`` of the frames
      along the rod, at the base, at ``config["nbFramesF"]`` equal steps from it (the first
      at the base again) and at the tip, placed by a DiscreteCosseratMapping from the strains
      and the base; with `buildCollision`, edge collision on them (:func:`addEdgeCollision`).

    The rod runs along the base frame's x axis; curvilinear abscissas start at the base's x.
    `last_frame` ({"orient", "index", "dist"}) adds frames carried by one of the frames.
    `nonColored` only changes the drawing. Pliant reads the rod as a
    :class:`pliant.fem.rod.RodBody` (:mod:`pliant.sofa.rods`)."""
    x, y, z = (float(v) for v in config["init_pos"])
    total = float(config["tot_length"])
    n_sections, n_frames = int(config["nbSectionS"]), int(config["nbFramesF"])
    last = last_frame or {"orient": [], "index": None, "dist": None}
    base = parent.addChild(name)
    base.addObject("EulerImplicitSolver", firstOrder=0, rayleighStiffness=0.2, rayleighMass=0.1)
    base.addObject("SparseLDLSolver", template="CompressedRowSparseMatrixd", name="solver")
    base.addObject("GenericConstraintCorrection")
    if rigidBase is None:
        base_node = base.addChild("rigidBase")
        base_dofs = base_node.addObject(
            "MechanicalObject", template="Rigid3d", name="RigidBaseMO",
            position=[x, y, z, *orientation],
        )  # fmt: skip
        base_node.addObject(
            "RestShapeSpringsForceField", name="spring", stiffness=5000, angularStiffness=5000,
            external_points=0, mstate="@RigidBaseMO", points=0, template="Rigid3d",
        )  # fmt: skip
    else:
        base_node = base.addChild(rigidBase)
        base_dofs = rigidBase.RigidBaseMO
    step = total / n_sections
    lengths = [step] * n_sections
    sections = [x + step * i for i in range(n_sections)] + [x + total]
    strains = base.addChild("rateAngularDeform")
    strain_dofs = strains.addObject(
        "MechanicalObject", template="Vec3d", name="rateAngularDeformMO",
        position=[[0.0, 0.0, 0.0]] * n_sections,
    )  # fmt: skip
    strains.addObject(
        "BeamHookeLawForceField", crossSectionShape="circular", length=lengths, radius=radius,
        youngModulus=youngModulus,
    )  # fmt: skip
    along = [i * total / n_frames for i in range(n_frames)]
    if last["index"] is not None and 1 <= int(last["index"]) <= n_frames:
        along[int(last["index"]) - 1] = float(last["dist"])
    abscissas = [x] + [x + s for s in along] + [x + total]
    frames = [[a, y, z, 0.0, 0.0, 0.0, 1.0] for a in abscissas]
    mapped = base_node.addChild("MappedFrames")
    strains.addChild(mapped)
    frame_dofs = mapped.addObject(
        "MechanicalObject", template="Rigid3d", name="FramesMO", position=frames
    )
    if buildCollision:
        points = [f[:3] for f in frames]
        edges = [k for i in range(len(points) - 1) for k in (i, i + 1)]
        addEdgeCollision(mapped, points, edges)
    mapped.addObject(
        "DiscreteCosseratMapping", curv_abs_input=sections, curv_abs_output=abscissas,
        input1=strain_dofs.getLinkPath(), input2=base_dofs.getLinkPath(),
        output=frame_dofs.getLinkPath(), debug=0, radius=radius, nonColored=nonColored,
    )  # fmt: skip
    for i, orient in enumerate(last["orient"]):
        carried = base.addChild(f"lastFrame_{i}")
        dofs = carried.addObject(
            "MechanicalObject", template="Rigid3d", name="RigidBaseMO",
            position=[x + float(last["dist"]), y, z, *orient],
        )  # fmt: skip
        carried.addObject(
            "RigidMapping", name="mapLastFrame", input=frame_dofs.getLinkPath(),
            output=dofs.getLinkPath(), index=last["index"], globalToLocalCoords=True,
        )  # fmt: skip
    return base


def express_point(base, point) -> list[float]:
    """A Rigid3 pose `point` (x y z, quaternion x y z w) relative to the pose `base`, as
    SofaGym documents it: the difference of the positions (world axes, not turned into the
    base's) and the rotation taking the base's orientation to the point's, base^-1 point."""
    base, point = np.asarray(base, dtype=float), np.asarray(point, dtype=float)
    turn = Rotation.from_quat(base[3:7]).inv() * Rotation.from_quat(point[3:7])
    quaternion = turn.as_quat()
    quaternion *= -1.0 if quaternion[3] < 0 else 1.0
    return [float(v) for v in (*(point[:3] - base[:3]), *quaternion)]


def header_members() -> dict:
    return {"addHeader": addHeader, "addVisu": addVisu}


def utils_members() -> dict:
    return {
        "addRigidObject": addRigidObject,
        "createCosserat": createCosserat,
        "addEdgeCollision": addEdgeCollision,
        "express_point": express_point,
    }
