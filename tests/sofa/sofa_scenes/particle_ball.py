"""A particle ball (a Vec3 MechanicalObject of one point with a SphereCollisionModel and a
UniformMass, as the Tripod tutorial's maze has) falling onto a floor beside a block held by its
base, and a goal marker (a sphere model with no solver nor mass) that stays where it is."""


def createScene(rootNode):
    rootNode.gravity = [0.0, 0.0, -9810.0]
    rootNode.dt = 0.01
    rootNode.addObject("FreeMotionAnimationLoop")
    rootNode.addObject("DefaultPipeline")
    rootNode.addObject("BruteForceDetection")
    rootNode.addObject(
        "RuleBasedContactManager", response="FrictionContactConstraint", responseParams="mu=0"
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
    ball.addObject("SparseLDLSolver")
    ball.addObject("MechanicalObject", name="ball_mo", position=[30.0, 5.0, 10.0])
    ball.addObject("UniformMass", totalMass=1e-4)
    ball.addObject("SphereCollisionModel", radius=2)
    goal = rootNode.addChild("Goal")
    goal.addObject("MechanicalObject", name="goal_mo", position=[[-20.0, 0.0, 3.0]])
    goal.addObject("SphereCollisionModel", radius=1.5)
    block = rootNode.addChild("Block")
    block.addObject("EulerImplicitSolver")
    block.addObject("SparseLDLSolver")
    block.addObject("MeshVTKLoader", name="loader", filename="block.vtu")
    block.addObject("MechanicalObject", name="dofs")
    block.addObject("UniformMass", totalMass=0.01)
    block.addObject("TetrahedronFEMForceField", youngModulus=1000.0, poissonRatio=0.3)
    block.addObject("BoxROI", name="base", box=[-1.0, -1.0, -1.0, 11.0, 11.0, 0.1])
    block.addObject("FixedConstraint", indices="@base.indices")
    block.addObject("PointCollisionModel")
    return rootNode
