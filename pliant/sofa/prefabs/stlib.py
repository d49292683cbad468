"""STLIB3's prefabs (``stlib3.scene``, ``stlib3.physics``, ``stlib3.visuals``,
``stlib3.solver``, ``stlib3.components``), written for Pliant from STLIB's documentation: each
adds to the scene the components STLIB documents for it, with its documented arguments and
defaults. Rigid shapes that STLIB loads from SOFA's shared meshes (``mesh/cube.obj``,
``mesh/floor.obj``) are written out here as their corners and faces; its ball
(``mesh/ball.obj``, a unit sphere) as a SphereCollisionModel of the same radius.
"""

from __future__ import annotations

import numpy as np

from pliant.sofa.prefabs.splib import AnimationManager, getOrientedBoxFromTransform
from pliant.sofa.sofapython3 import Prefab
from pliant.sofa.tree import SceneNode


def _loader_for(filename: str) -> str:
    suffix = str(filename).rsplit(".", 1)[-1].lower()
    return {"msh": "MeshGmshLoader", "obj": "MeshOBJLoader", "stl": "MeshSTLLoader"}.get(
        suffix, "MeshVTKLoader"
    )


def _plugins(node: SceneNode, plugins, where: str) -> None:
    holder = node.addChild(where)
    for name in [*(plugins or []), "SofaPython3"]:
        holder.addObject("RequiredPlugin", name=name, printLog=False)
    holder.addObject("OglSceneFrame", style="Arrows", alignment="TopRight")


def MainHeader(  # noqa: N802 (STLIB's name)
    node: SceneNode,
    gravity=(0.0, -9.8, 0.0),
    dt: float = 0.01,
    plugins=(),
    repositoryPaths=(),  # noqa: N803
    doDebug: bool = False,  # noqa: N803
) -> SceneNode:
    """The root's settings: gravity, time step, plugins (in a ``Config`` child), the visual
    loop and an :func:`AnimationManager` for :func:`pliant.sofa.prefabs.splib.animate`."""
    node.addObject("VisualStyle")
    node.gravity = list(gravity)
    node.dt = dt
    node.addObject("DefaultVisualManagerLoop")
    _plugins(node, list(plugins), "Config")
    AnimationManager(node)
    return node


def ContactHeader(  # noqa: N802
    applyTo: SceneNode,  # noqa: N803
    alarmDistance: float,  # noqa: N803
    contactDistance: float,  # noqa: N803
    frictionCoef: float = 0.0,  # noqa: N803
) -> SceneNode:
    """The collision pipeline with frictional contact: detection with ``alarmDistance`` and
    ``contactDistance``, friction ``frictionCoef``, and the constraint-based animation loop."""
    if not applyTo.hasObject("CollisionPipeline"):
        applyTo.addObject("CollisionPipeline")
    applyTo.addObject("BruteForceBroadPhase")
    applyTo.addObject("BVHNarrowPhase")
    applyTo.addObject(
        "RuleBasedContactManager",
        name="Response",
        response="FrictionContactConstraint",
        responseParams=f"mu={frictionCoef}",
    )
    applyTo.addObject(
        "LocalMinDistance",
        alarmDistance=alarmDistance,
        contactDistance=contactDistance,
        angleCone=0.01,
    )
    if not applyTo.hasObject("FreeMotionAnimationLoop"):
        applyTo.addObject("FreeMotionAnimationLoop")
    if not applyTo.hasObject("BlockGaussSeidelConstraintSolver"):
        applyTo.addObject("BlockGaussSeidelConstraintSolver", tolerance=1e-6, maxIterations=1000)
    return applyTo


def DefaultSolver(node: SceneNode, iterative: bool = True) -> SceneNode:  # noqa: N802
    """An implicit Euler integrator with a linear solver (CG or a sparse LDL)."""
    node.addObject("EulerImplicitSolver", name="TimeIntegrationSchema")
    if iterative:
        node.addObject("CGLinearSolver", name="LinearSolver", iterations=25, tolerance=1e-5)
    else:
        node.addObject("SparseLDLSolver", name="LinearSolver")
    return node


def Scene(  # noqa: N802
    root: SceneNode,
    gravity=(0.0, -9.81, 0.0),
    dt: float = 0.01,
    plugins=(),
    repositoryPaths=(),  # noqa: N803
    iterative: bool = True,
) -> SceneNode:
    """The root set up as STLIB's Scene: gravity and time step, and the methods
    ``addMainHeader`` (an animation manager, ``Settings``, ``Modelling`` and ``Simulation``
    children, the last with a default solver), ``addSettings``, ``addModelling``,
    ``addSimulation``, ``addSolver`` and ``addContact`` (a :func:`ContactHeader`)."""
    root.gravity = list(gravity)
    root.dt = dt
    root.addObject("VisualStyle")

    def add_settings(plugins=plugins, repositoryPaths=repositoryPaths):  # noqa: N803
        settings = root.addChild("Settings")
        _plugins(settings, list(plugins), "Plugins")
        settings.addObject("AttachBodyButtonSetting", name="mouseButton")
        return root

    def add_modelling():
        root.addChild("Modelling")
        return root

    def add_simulation():
        DefaultSolver(root.addChild("Simulation"), iterative)
        return root

    def add_main_header(plugins=plugins, repositoryPaths=repositoryPaths, doDebug=False):  # noqa: N803
        AnimationManager(root)
        add_settings(plugins, repositoryPaths)
        add_modelling()
        add_simulation()

    def add_contact(alarmDistance=1.0, contactDistance=0.1, frictionCoef=1.0):  # noqa: N803
        ContactHeader(root, alarmDistance, contactDistance, frictionCoef)
        return root

    root.addMainHeader = add_main_header
    root.addSettings = add_settings
    root.addModelling = add_modelling
    root.addSimulation = add_simulation
    root.addSolver = lambda node: DefaultSolver(node, iterative)
    root.addContact = add_contact
    return root


class VisualModel(Prefab):
    """A surface mesh drawn by SOFA (an OglModel); nothing Pliant computes."""

    prefabParameters = [  # noqa: RUF012
        {"name": "visualMeshPath", "default": ""},
        {"name": "translation", "default": [0.0, 0.0, 0.0]},
        {"name": "rotation", "default": [0.0, 0.0, 0.0]},
        {"name": "scale", "default": [1.0, 1.0, 1.0]},
        {"name": "color", "default": [1.0, 1.0, 1.0, 1.0]},
    ]

    def init(self) -> None:
        self.addObject("OglModel", name="OglModel", color=list(self.color.value))


def CollisionMesh(  # noqa: N802
    attachedTo: SceneNode | None = None,  # noqa: N803
    surfaceMeshFileName: str | None = None,  # noqa: N803
    name: str = "collision",
    rotation=(0.0, 0.0, 0.0),
    translation=(0.0, 0.0, 0.0),
    scale=(1.0, 1.0, 1.0),
    collisionGroup=None,  # noqa: N803
    mappingType: str | None = "BarycentricMapping",  # noqa: N803
) -> SceneNode:
    """A child of `attachedTo` whose surface mesh collides (points, lines, triangles),
    mapped onto its parent's degrees of freedom."""
    node = attachedTo.addChild(name)
    node.addObject(
        _loader_for(surfaceMeshFileName),
        name="loader",
        filename=surfaceMeshFileName,
        rotation=list(rotation),
        translation=list(translation),
        scale3d=list(scale),
    )
    node.addObject("MeshTopology", src="@loader")
    node.addObject("MechanicalObject")
    group = {"group": collisionGroup} if collisionGroup else {}
    for model in ("PointCollisionModel", "LineCollisionModel", "TriangleCollisionModel"):
        node.addObject(model, **group)
    if mappingType is not None:
        node.addObject(mappingType)
    return node


class ElasticMaterialObject(Prefab):
    """A deformable body from a volume mesh: an implicit Euler integrator with a sparse
    direct solver (unless ``solverName`` names the scene's), the mesh loaded with its
    transform, a tetrahedral topology, ``dofs``, a uniform ``totalMass``, a corotational FEM
    (``youngModulus``, ``poissonRatio``, SOFA's "large" frame), a constraint correction, and
    optional collision and visual children."""

    prefabParameters = [  # noqa: RUF012
        {"name": "volumeMeshFileName", "default": ""},
        {"name": "rotation", "default": [0.0, 0.0, 0.0]},
        {"name": "translation", "default": [0.0, 0.0, 0.0]},
        {"name": "scale", "default": [1.0, 1.0, 1.0]},
        {"name": "surfaceMeshFileName", "default": ""},
        {"name": "collisionMesh", "default": ""},
        {"name": "withConstrain", "default": True},
        {"name": "surfaceColor", "default": [1.0, 1.0, 1.0, 1.0]},
        {"name": "poissonRatio", "default": 0.3},
        {"name": "youngModulus", "default": 18000.0},
        {"name": "totalMass", "default": 1.0},
        {"name": "solverName", "default": ""},
    ]

    def init(self) -> None:
        placed = {
            "rotation": list(self.rotation.value),
            "translation": list(self.translation.value),
            "scale3d": list(self.scale.value),
        }
        if not self.solverName.value:
            self.addObject("EulerImplicitSolver", name="integration")
            self.addObject("SparseLDLSolver", name="solver")
        mesh = str(self.volumeMeshFileName.value)
        self.addObject(_loader_for(mesh), name="loader", filename=mesh, **placed)
        self.addObject(
            "TetrahedronSetTopologyContainer",
            name="container",
            position="@loader.position",
            tetrahedra="@loader.tetrahedra",
        )
        self.addObject("MechanicalObject", name="dofs", template="Vec3")
        self.addObject("UniformMass", name="mass", totalMass=self.totalMass.value)
        self.addObject(
            "TetrahedronFEMForceField",
            name="forcefield",
            template="Vec3",
            method="large",
            poissonRatio=self.poissonRatio.value,
            youngModulus=self.youngModulus.value,
        )
        if self.withConstrain.value:
            self.addObject("LinearSolverConstraintCorrection", name="correction")
        if self.collisionMesh.value:
            CollisionMesh(self, str(self.collisionMesh.value), "CollisionModel", **_placed(placed))
        if self.surfaceMeshFileName.value:
            self.addVisualModel(str(self.surfaceMeshFileName.value), self.surfaceColor.value)

    def addVisualModel(self, filename, color, *_placement, **_named) -> SceneNode:  # noqa: N802
        visual = self.addChild(VisualModel(visualMeshPath=filename, color=list(color)))
        visual.addObject("BarycentricMapping", name="mapping")
        return visual


def _placed(placed: dict) -> dict:
    return {
        "rotation": placed["rotation"],
        "translation": placed["translation"],
        "scale": placed["scale3d"],
    }


def FixedBox(  # noqa: N802
    applyTo: SceneNode | None = None,  # noqa: N803
    atPositions=(-1.0, -1.0, -1.0, 1.0, 1.0, 1.0),  # noqa: N803
    name: str = "FixedBox",
    doVisualization: bool = False,  # noqa: N803
    position=None,
    constraintStrength: float = 1e12,  # noqa: N803
    doRecomputeDuringSimulation: bool = False,  # noqa: N803
) -> SceneNode:
    """A child of `applyTo` holding the nodes inside the box (xmin ymin zmin xmax ymax zmax)
    at their rest positions with stiff springs (STLIB's stiffness 1e12)."""
    node = applyTo.addChild(name)
    where = {} if position is None else {"position": position}
    node.addObject(
        "BoxROI", name="BoxROI", box=list(atPositions), drawBoxes=doVisualization, **where
    )
    node.addObject("RestShapeSpringsForceField", points="@BoxROI.indices", stiffness=1e12)
    return node


# SOFA's shared meshes that STLIB's rigid shapes load: a cube with corners at +-1 and a flat
# square floor (y = 0, normal +y), as corners and triangles.
_CUBE = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=float)
_CUBE_FACES = [
    [0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
    [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3],
]  # fmt: skip
_FLOOR = np.array([[-1, 0, -1], [1, 0, -1], [1, 0, 1], [-1, 0, 1]], dtype=float)
_FLOOR_FACES = [[0, 2, 1], [0, 3, 2]]
SHAPES = {"cube": (_CUBE, _CUBE_FACES), "floor": (_FLOOR, _FLOOR_FACES)}
# SOFA's shared meshes a scene may name (SofaGym's carts: mesh/cube.obj), written out: SOFA
# finds them in its share folder, beside no scene.
SHARED_MESHES = {"mesh/cube.obj": SHAPES["cube"]}


def RigidObject(  # noqa: N802
    name: str = "RigidObject",
    surfaceMeshFileName: str | None = None,  # noqa: N803
    translation=(0.0, 0.0, 0.0),
    rotation=(0.0, 0.0, 0.0),
    uniformScale: float = 1.0,  # noqa: N803
    totalMass: float = 1.0,  # noqa: N803
    volume: float = 1.0,
    inertiaMatrix=(1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0),  # noqa: N803
    color=(1.0, 1.0, 1.0, 1.0),
    collisionGroup: str = "",  # noqa: N803
    isAStaticObject: bool = False,  # noqa: N803
    parent: SceneNode | None = None,
    shape: str | None = None,
) -> SceneNode:
    """A rigid body: a Rigid3 ``mstate`` placed by `translation` and `rotation` (Euler
    angles, degrees), its mass (``totalMass``, ``volume``, ``inertiaMatrix``), a solver unless
    static, and a ``collision`` child (points, lines, triangles) mapped rigidly; `shape` names
    one of :data:`SHAPES` written out instead of a mesh file, or "ball": a sphere of radius
    `uniformScale` on the frame (SOFA's unit ball scaled)."""
    node = SceneNode(name) if parent is None else parent.addChild(name)
    node.addObject(
        "MechanicalObject",
        name="mstate",
        template="Rigid3",
        translation2=list(translation),
        rotation2=list(rotation),
        showObjectScale=uniformScale,
    )
    node.addObject(
        "UniformMass", name="mass", vertexMass=[totalMass, volume, *np.ravel(inertiaMatrix)]
    )
    if not isAStaticObject:
        node.addObject("EulerImplicitSolver")
        node.addObject("CGLinearSolver", iterations=25, tolerance=1e-5)
    if shape is None and surfaceMeshFileName is None:
        return node
    collision = node.addChild("collision")
    still = {"moving": False, "simulated": False} if isAStaticObject else {}
    group = {"group": collisionGroup} if collisionGroup else {}
    if shape == "ball":
        collision.addObject("MechanicalObject", position=[0.0, 0.0, 0.0])
        collision.addObject("SphereCollisionModel", radius=uniformScale, **still, **group)
    elif shape is not None:
        points, faces = SHAPES[shape]
        collision.addObject("MeshTopology", triangles=np.array(faces).ravel().tolist())
        collision.addObject("MechanicalObject", position=(uniformScale * points).tolist())
    else:
        collision.addObject(
            "MeshOBJLoader", name="loader", filename=surfaceMeshFileName, scale=uniformScale
        )
        collision.addObject("MeshTopology", src="@loader")
        collision.addObject("MechanicalObject")
    for model in ("TriangleCollisionModel", "LineCollisionModel", "PointCollisionModel"):
        if shape != "ball":
            collision.addObject(model, **still, **group)
    collision.addObject("RigidMapping")
    visual = node.addChild(VisualModel(name="visual", color=list(color)))
    visual.addObject("RigidMapping")
    return node


def Cube(node: SceneNode, **kwargs) -> SceneNode:  # noqa: N802
    """A rigid cube (corners at +-uniformScale)."""
    kwargs.setdefault("name", "Cube")
    return RigidObject(parent=node, shape="cube", **kwargs)


def Floor(node: SceneNode, **kwargs) -> SceneNode:  # noqa: N802
    """A flat rigid floor (the plane y = 0 before its rotation and translation)."""
    kwargs.setdefault("name", "Floor")
    return RigidObject(parent=node, shape="floor", **kwargs)


def Sphere(node: SceneNode, **kwargs) -> SceneNode:  # noqa: N802
    """A rigid ball of radius uniformScale (STLIB's SOFA's unit ball, mesh/ball.obj, collides
    by its triangles; Pliant's ball is the exact sphere, a SphereCollisionModel)."""
    kwargs.setdefault("name", "Sphere")
    return RigidObject(parent=node, shape="ball", **kwargs)


def addOrientedBoxRoi(  # noqa: N802
    parent: SceneNode,
    position,
    name: str = "BoxROI",
    translation=(0.0, 0.0, 0.0),
    eulerRotation=(0.0, 0.0, 0.0),  # noqa: N803
    scale=(1.0, 1.0, 1.0),
    drawBoxes: bool = False,  # noqa: N803
):
    """A BoxROI whose box is a unit cube scaled, rotated (Euler angles, degrees) and
    translated: SOFA's ``orientedBox`` (three corners and a depth)."""
    return parent.addObject(
        "BoxROI",
        name=name,
        position=position,
        orientedBox=getOrientedBoxFromTransform(translation, None, eulerRotation, scale),
        drawBoxes=drawBoxes,
    )
