"""A block held by its base pushes up a rigid ball lying on its top face: the ball a Rigid3
MechanicalObject with a SphereCollisionModel of its own, the floor a still triangle pair."""


def createScene(rootNode):
    rootNode.gravity = [0.0, 0.0, -9810.0]
    rootNode.dt = 0.01
    rootNode.addObject("FreeMotionAnimationLoop")
    rootNode.addObject("GenericConstraintSolver", tolerance=1e-8, maxIterations=1000)
    rootNode.addObject("CollisionPipeline")
    rootNode.addObject("BruteForceBroadPhase")
    rootNode.addObject("BVHNarrowPhase")
    rootNode.addObject(
        "RuleBasedContactManager", response="FrictionContactConstraint", responseParams="mu=0.2"
    )
    rootNode.addObject("LocalMinDistance", alarmDistance=1.0, contactDistance=0.1)
    floor = rootNode.addChild("Floor")
    floor.addObject("MeshTopology", triangles=[0, 1, 2, 0, 2, 3])
    floor.addObject(
        "MechanicalObject", position=[[-50, -50, 0], [50, -50, 0], [50, 50, 0], [-50, 50, 0]]
    )
    floor.addObject("TriangleCollisionModel", moving=False, simulated=False)
    ball = rootNode.addChild("Ball")
    ball.addObject("EulerImplicitSolver")
    ball.addObject("CGLinearSolver", iterations=25, tolerance=1e-8, threshold=1e-8)
    ball.addObject(
        "MechanicalObject", template="Rigid3", position=[5.0, 5.0, 14.5, 0.0, 0.0, 0.0, 1.0]
    )
    ball.addObject(
        "UniformMass", vertexMass=[0.002, 65.4, 6.4, 0.0, 0.0, 0.0, 6.4, 0.0, 0.0, 0.0, 6.4]
    )
    ball.addObject("SphereCollisionModel", radius=4.0)
    ball.addObject("UncoupledConstraintCorrection")
    block = rootNode.addChild("Block")
    block.addObject("EulerImplicitSolver")
    block.addObject("SparseLDLSolver")
    block.addObject("MeshVTKLoader", name="loader", filename="block.vtu")
    block.addObject("MechanicalObject", name="dofs")
    block.addObject("UniformMass", totalMass=0.01)
    block.addObject("TetrahedronFEMForceField", youngModulus=50.0, poissonRatio=0.3)
    block.addObject("BoxROI", name="base", box=[-1.0, -1.0, -1.0, 11.0, 11.0, 0.1])
    block.addObject("FixedConstraint", indices="@base.indices")
    block.addObject("ConstantForceField", force=[0.0, 0.0, 10.0])
    block.addObject("PointCollisionModel")
    block.addObject("LinearSolverConstraintCorrection")
    return rootNode
