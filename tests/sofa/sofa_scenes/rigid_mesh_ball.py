"""SofaGym's addRigidObject: a rigid ball given by a surface mesh (ball.obj) and a density,
above STLIB's Floor, beside a block held by its base."""

from sofagym.header import addHeader
from sofagym.utils import addRigidObject
from stlib3.physics.rigid import Floor


def createScene(rootNode):
    addHeader(
        rootNode, alarmDistance=1.0, contactDistance=0.1, gravity=[0.0, 0.0, -9810.0], dt=0.01
    )
    Floor(rootNode, rotation=[90.0, 0.0, 0.0], isAStaticObject=True)
    addRigidObject(
        rootNode,
        filename="ball.obj",
        position=[40.0, 5.0, 20.0, 0.0, 0.0, 0.0, 1.0],
        density=2e-6,
        name="Ball",
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
