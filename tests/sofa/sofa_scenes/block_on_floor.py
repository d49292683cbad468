"""A block falling onto STLIB's Floor, colliding through a PointCollisionModel on its own
MechanicalObject, beside STLIB's rigid Cube; a controller moves the goal an effector follows."""

import Sofa.Core
from stlib3.physics.rigid import Cube, Floor
from stlib3.scene import ContactHeader, MainHeader


class GoalController(Sofa.Core.Controller):
    def __init__(self, *args, **kwargs):
        Sofa.Core.Controller.__init__(self, *args, **kwargs)
        self.goal = kwargs["goal"]

    def onAnimateBeginEvent(self, event):
        with self.goal.position.writeable() as goal:
            goal[0][2] += 1.0  # 1 mm up each step


def createScene(rootNode):
    MainHeader(rootNode, gravity=[0.0, 0.0, -9810.0], dt=0.01)
    ContactHeader(rootNode, alarmDistance=1.0, contactDistance=0.1, frictionCoef=0.3)
    Floor(rootNode, translation=[0.0, 0.0, -2.0], rotation=[90.0, 0.0, 0.0], isAStaticObject=True)
    Cube(rootNode, translation=[30.0, 5.0, 3.0], uniformScale=3.0, totalMass=0.01)
    goal = rootNode.addChild("Goal")
    goal_dofs = goal.addObject("MechanicalObject", name="goalMO", position=[[5.0, 5.0, 10.0]])
    block = rootNode.addChild("Block")
    block.addObject("EulerImplicitSolver")
    block.addObject("SparseLDLSolver")
    block.addObject("MeshVTKLoader", name="loader", filename="block.vtu")
    block.addObject("MechanicalObject", name="dofs")
    block.addObject("UniformMass", totalMass=0.01)
    block.addObject("TetrahedronFEMForceField", youngModulus=1000.0, poissonRatio=0.3)
    block.addObject("PointCollisionModel")
    block.addObject("LinearSolverConstraintCorrection")
    tip = block.addChild("Tip")
    tip.addObject("MechanicalObject", position=[[5.0, 5.0, 10.0]])
    tip.addObject("PositionEffector", indices=[0], effectorGoal="@../../Goal/goalMO.position")
    tip.addObject("BarycentricMapping")
    rootNode.addObject(GoalController(goal=goal_dofs))
    return rootNode
