"""A rigid cart (Rigid3, turned 90 degrees about z) on a rail (a PartialFixedConstraint that
holds all but its x translation), pulled along x by the gravity's x component, carrying a
Goal by a RigidMapping: a MechanicalObject given no position, one point at the origin by
SOFA's default, moved by its translation (SofaGym's CatchTheObject). A Marker elsewhere with
no position, and a block held by its base (the model's deformable body), 5 mm under the
cart's sphere, and a still sphere far away (a static obstacle). Written for Pliant's
tests."""


def createScene(rootNode, config=None):
    rootNode.dt = 0.01
    rootNode.gravity = [1000.0, 0.0, -9810.0]
    rootNode.addObject("FreeMotionAnimationLoop")
    rootNode.addObject("GenericConstraintSolver", tolerance=1e-12, maxIterations=1000)
    rootNode.addObject("CollisionPipeline")
    rootNode.addObject("BruteForceBroadPhase")
    rootNode.addObject("BVHNarrowPhase")
    rootNode.addObject("CollisionResponse", response="FrictionContactConstraint")
    rootNode.addObject("LocalMinDistance", alarmDistance=0.5, contactDistance=0.01)

    block = rootNode.addChild("Block")
    block.addObject("EulerImplicitSolver")
    block.addObject("SparseLDLSolver")
    block.addObject("MeshVTKLoader", name="loader", filename="block.vtu")
    block.addObject("MeshTopology", src="@loader")
    block.addObject("MechanicalObject", name="dofs")
    block.addObject("UniformMass", totalMass=0.005)
    block.addObject("TetrahedronFEMForceField", youngModulus=100.0, poissonRatio=0.3)
    block.addObject("BoxROI", name="base", box=[-1.0, -1.0, -0.1, 13.0, 13.0, 0.1])
    block.addObject("FixedConstraint", indices="@base.indices")
    block.addObject("LinearSolverConstraintCorrection")
    block.addObject("PointCollisionModel")

    cart = rootNode.addChild("cart")
    cart.addObject("EulerImplicitSolver")
    cart.addObject("CGLinearSolver", tolerance=1e-5, iterations=25)
    s = 0.5**0.5
    cart.addObject("MechanicalObject", template="Rigid3", position=[0, 0, 10, 0, 0, s, s])
    cart.addObject("UniformMass", totalMass=1.0)
    cart.addObject("PartialFixedConstraint", fixedDirections=[0, 1, 1, 1, 1, 1])
    cart.addObject("UncoupledConstraintCorrection")
    cart.addObject("SphereCollisionModel", radius=1.0)
    goal = cart.addChild("Goal")
    goal.addObject("MechanicalObject", name="GoalMO", translation=[3, 2, 1])
    goal.addObject("RigidMapping")

    post = rootNode.addChild("Post")  # a still sphere far away: a static obstacle
    post.addObject("MechanicalObject", template="Rigid3", position=[50, 50, 50, 0, 0, 0, 1])
    post.addObject("SphereCollisionModel", radius=1.0, moving=False, simulated=False)

    marker = rootNode.addChild("Marker")
    marker.addObject("MechanicalObject", name="dofs", translation=[1, 2, 3])
    return rootNode
