"""A block with a cavity whose pressure SPLIB's animate ramps from 0 to 30 over 0.05 s,
written with STLIB's MainHeader and SoftRobots' PneumaticCavity (pressure mode), on a
FastTetrahedralCorotationalForceField held by a BoxROI given max corner first."""

from softrobots.actuators import PneumaticCavity
from splib3.animation import animate
from stlib3.scene import MainHeader

PEAK = 30.0  # pressure at the end of the ramp
RAMP = 0.05  # seconds


def inflate(cavity, factor):
    cavity.value = [PEAK * factor]


def createScene(rootNode):
    MainHeader(rootNode, gravity=[0.0, 0.0, 0.0], dt=0.01, plugins=["SoftRobots"])
    rootNode.addObject("VisualStyle", displayFlags="showVisualModels")
    block = rootNode.addChild("Block")
    block.addObject("EulerImplicitSolver", rayleighStiffness=0.1, rayleighMass=0.1)
    block.addObject("SparseLDLSolver")
    block.addObject("MeshVTKLoader", name="loader", filename="block.vtu")
    block.addObject("TetrahedronSetTopologyContainer", name="container", src="@loader")
    block.addObject("TetrahedronSetTopologyModifier")
    block.addObject("MechanicalObject", name="dofs")
    block.addObject("UniformMass", totalMass=0.01)
    block.addObject("FastTetrahedralCorotationalForceField", youngModulus=1000.0, poissonRatio=0.3)
    block.addObject("BoxROI", name="base", box=[0.1, 11.0, 11.0, -1.0, -1.0, -1.0])
    block.addObject("FixedProjectiveConstraint", indices="@base.indices")
    block.addObject("LinearSolverConstraintCorrection")
    cavity = PneumaticCavity(
        surfaceMeshFileName="cavity.stl",
        attachedAsAChildOf=block,
        name="Cavity",
        valueType="pressure",
    )
    visual = block.addChild("Visual")
    visual.addObject("OglModel", src="@../loader", color=[0.5, 0.5, 1.0, 1.0])
    visual.addObject("IdentityMapping")
    animate(inflate, {"cavity": cavity.SurfacePressureConstraint}, RAMP)
    return rootNode
