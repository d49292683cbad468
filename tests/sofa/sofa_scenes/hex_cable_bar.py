"""A bar voxelised by a SparseGridTopology into corotational hexahedra (SOFA's
HexahedronFEMForceField, "large" method), held at one end by a FixedConstraint on a BoxROI and
bent by a cable whose controller pulls 0.5 mm more each step; the cable's points follow the
grid through a BarycentricMapping."""

import Sofa.Core

STEP = 0.5  # mm of cable pulled per step


class Pull(Sofa.Core.Controller):
    def __init__(self, *args, **kwargs):
        Sofa.Core.Controller.__init__(self, *args, **kwargs)
        self.cable = kwargs["cable"]

    def onAnimateBeginEvent(self, event):
        self.cable.value = [self.cable.value.value[0] + STEP]


def createScene(rootNode):
    rootNode.gravity = [0.0, -9810.0, 0.0]
    rootNode.dt = 0.01
    rootNode.addObject("RequiredPlugin", name="SoftRobots")
    rootNode.addObject("FreeMotionAnimationLoop")
    rootNode.addObject("GenericConstraintSolver", tolerance=1e-8, maxIterations=200)
    rootNode.addObject("VisualStyle", displayFlags="showBehaviorModels showForceFields")
    bar = rootNode.addChild("Bar")
    bar.addObject("EulerImplicitSolver", rayleighStiffness=0.1, rayleighMass=0.1)
    bar.addObject("SparseLDLSolver")
    bar.addObject("MeshSTLLoader", name="loader", filename="bar.stl")
    bar.addObject("SparseGrid", name="grid", src="@loader", n=[7, 3, 3])
    bar.addObject("MechanicalObject", name="dofs", src="@grid")
    bar.addObject("UniformMass", totalMass=0.05)
    bar.addObject("HexahedronFEMForceField", youngModulus=500, poissonRatio=0.3)
    bar.addObject("BoxROI", name="box", box=[-1, -1, -1, 1, 11, 11])
    bar.addObject("FixedConstraint", indices="@box.indices")
    bar.addObject("LinearSolverConstraintCorrection")
    cable = bar.addChild("Cable")
    cable.addObject("MechanicalObject", position=[[x, 8.0, 5.0] for x in (10, 20, 30, 40, 50, 60)])
    pulled = cable.addObject(
        "CableConstraint", indices=list(range(6)), pullPoint=[0.0, 8.0, 5.0], value=0.0
    )
    cable.addObject("BarycentricMapping")
    rootNode.addObject(Pull(name="pull", cable=pulled))
    return rootNode
