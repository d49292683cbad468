"""A rigid ball (Rigid3, 2 mm, 0.2 g) dropped 0.05 mm onto a soft block held at its base,
written for Pliant's tests: the block collides by triangles only (a TriangleCollisionModel in
group 1 on its surface mesh, block.stl, carried by a BarycentricMapping), the ball by its
SphereCollisionModel (no group): SOFA tests the sphere against the block's triangles, and
nothing else touches. With config {"massless": True} the block has no mass and is held by
rest-shape springs at its base (SofaGym's BubbleMotion board)."""


def createScene(rootNode, config=None):
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

    block = rootNode.addChild("Block")
    block.addObject("EulerImplicitSolver", rayleighMass=5.0, rayleighStiffness=0.0)
    block.addObject("SparseLDLSolver")
    block.addObject("MeshVTKLoader", name="loader", filename="block.vtu")
    block.addObject("MeshTopology", src="@loader")
    block.addObject("MechanicalObject", name="dofs")
    massless = bool((config or {}).get("massless", False))
    if not massless:
        block.addObject("UniformMass", totalMass=0.005)
    block.addObject("TetrahedronFEMForceField", youngModulus=100.0, poissonRatio=0.3)
    block.addObject("BoxROI", name="base", box=[-1.0, -1.0, -0.1, 13.0, 13.0, 0.1])
    if massless:  # held by springs to its rest shape, as SofaGym's BubbleMotion board
        block.addObject("RestShapeSpringsForceField", points="@base.indices", stiffness=1e4)
    else:
        block.addObject("FixedConstraint", indices="@base.indices")
    block.addObject("LinearSolverConstraintCorrection")
    surface = block.addChild("Collision")
    surface.addObject("MeshSTLLoader", name="loader", filename="block.stl")
    surface.addObject("MeshTopology", src="@loader")
    surface.addObject("MechanicalObject")
    surface.addObject("TriangleCollisionModel", group=1)
    surface.addObject("BarycentricMapping")

    ball = rootNode.addChild("Ball")
    ball.addObject("EulerImplicitSolver")
    ball.addObject("CGLinearSolver", tolerance=1e-5, iterations=25)
    ball.addObject("MechanicalObject", template="Rigid3", position=[5.9, 6.3, 6.06, 0, 0, 0, 1])
    ball.addObject("UniformMass", totalMass=0.0002)
    ball.addObject("UncoupledConstraintCorrection")
    ball.addObject("SphereCollisionModel", radius=2.0)
    return rootNode
