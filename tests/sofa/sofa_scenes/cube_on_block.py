"""A soft cube (6 mm, 1 g) dropped 0.05 mm onto a soft block held at its base, written for
Pliant's tests: two deformable bodies whose collision meshes (Point, Line and Triangle models,
no group in common) SOFA tests against each other. The configuration picks where the models
sit:

    own: on each body's own MechanicalObject (the body's boundary triangles), instead of a
        child node carrying the surface mesh (cube.stl, block.stl) by a BarycentricMapping;
    groups: the bodies' collision group (the same group: they do not touch).
"""


def _collision(node, name, config):
    models = node
    if not config.get("own"):
        models = node.addChild("Collision")
        models.addObject("MeshSTLLoader", name="loader", filename=f"{name}.stl")
        models.addObject("MeshTopology", src="@loader")
        models.addObject("MechanicalObject")
    group = config.get("groups", {}).get(name)
    extra = {} if group is None else {"group": group}
    models.addObject("TriangleCollisionModel", **extra)
    models.addObject("LineCollisionModel", **extra)
    models.addObject("PointCollisionModel", **extra)
    if models is not node:
        models.addObject("BarycentricMapping")


def _body(root, name, mass, config):
    node = root.addChild(name.capitalize())
    node.addObject("EulerImplicitSolver", rayleighMass=5.0, rayleighStiffness=0.0)
    node.addObject("SparseLDLSolver")
    node.addObject("MeshVTKLoader", name="loader", filename=f"{name}.vtu")
    node.addObject("MeshTopology", src="@loader")
    node.addObject("MechanicalObject", name="dofs")
    node.addObject("UniformMass", totalMass=mass)
    node.addObject("TetrahedronFEMForceField", youngModulus=100.0, poissonRatio=0.3)
    if name == "block":
        node.addObject("BoxROI", name="base", box=[-1.0, -1.0, -0.1, 13.0, 13.0, 0.1])
        node.addObject("FixedConstraint", indices="@base.indices")
    node.addObject("LinearSolverConstraintCorrection")
    _collision(node, name, config)


def createScene(rootNode, config=None):
    config = config or {}
    rootNode.dt = 0.01
    rootNode.gravity = [0.0, 0.0, -9810.0]
    rootNode.addObject("FreeMotionAnimationLoop")
    rootNode.addObject("GenericConstraintSolver", tolerance=1e-12, maxIterations=1000)
    rootNode.addObject("CollisionPipeline")
    rootNode.addObject("BruteForceBroadPhase")
    rootNode.addObject("BVHNarrowPhase")
    rootNode.addObject(
        "CollisionResponse", response="FrictionContactConstraint", responseParams="mu=0.5"
    )
    rootNode.addObject("LocalMinDistance", alarmDistance=0.5, contactDistance=0.01)
    _body(rootNode, "block", 0.005, config)
    _body(rootNode, "cube", 0.001, config)
    return rootNode
