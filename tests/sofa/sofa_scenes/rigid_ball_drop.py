"""STLIB's Sphere (a rigid ball of radius 5 mm) falling onto STLIB's Floor beside a block held
by its base, and a still Sphere (isAStaticObject) 1 mm above the block: an obstacle."""

from stlib3.physics.rigid import Floor, Sphere
from stlib3.scene import ContactHeader, MainHeader


def createScene(rootNode):
    MainHeader(rootNode, gravity=[0.0, 0.0, -9810.0], dt=0.01)
    ContactHeader(rootNode, alarmDistance=1.0, contactDistance=0.1, frictionCoef=0.3)
    Floor(rootNode, translation=[0.0, 0.0, 0.0], rotation=[90.0, 0.0, 0.0], isAStaticObject=True)
    Sphere(
        rootNode,
        name="Ball",
        translation=[40.0, 5.0, 20.0],
        uniformScale=5.0,
        totalMass=0.01,
        volume=523.6,
        inertiaMatrix=[10.0, 0.0, 0.0, 0.0, 10.0, 0.0, 0.0, 0.0, 10.0],
    )
    Sphere(
        rootNode, name="Still", translation=[5.0, 5.0, 14.0], uniformScale=3.0, isAStaticObject=True
    )
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
