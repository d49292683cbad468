"""A cantilever pulled by a cable whose controller raises the pull by 0.2 mm each step,
written as SoftRobots users write scenes: STLIB's Scene, ElasticMaterialObject and FixedBox,
SoftRobots' PullingCable, a Sofa.Core.Controller, and visual components Pliant ignores."""

import Sofa.constants.Key as Key
import Sofa.Core
from softrobots.actuators import PullingCable
from stlib3.physics.constraints import FixedBox
from stlib3.physics.deformable import ElasticMaterialObject
from stlib3.scene import Scene

STEP = 0.2  # mm of cable pulled per step


class CableController(Sofa.Core.Controller):
    def __init__(self, *args, **kwargs):
        Sofa.Core.Controller.__init__(self, *args, **kwargs)
        self.cable = kwargs["cable"]
        self.tips = []  # the body's last node after each step, read back from the data

    def onAnimateBeginEvent(self, event):
        self.cable.value = [self.cable.value.value[0] + STEP]

    def onAnimateEndEvent(self, event):
        body = self.getContext().getChild("Simulation").getChild("Modelling")
        self.tips.append(body.Beam.dofs.position.value[-1].copy())

    def onKeypressedEvent(self, event):
        if event["key"] == Key.uparrow:
            self.cable.value = [self.cable.value.value[0] + 1.0]


def createScene(rootNode):
    scene = Scene(rootNode, gravity=[0.0, -9810.0, 0.0], dt=0.01, iterative=False)
    scene.addMainHeader()
    rootNode.addObject("BackgroundSetting", color=[1.0, 1.0, 1.0, 1.0])
    rootNode.addObject("LightManager")
    rootNode.addObject("OglSceneFrame", style="Arrows", alignment="TopRight")
    rootNode.VisualStyle.displayFlags = "showBehaviorModels showForceFields"
    beam = ElasticMaterialObject(
        name="Beam",
        volumeMeshFileName="beam.vtu",
        youngModulus=500.0,
        poissonRatio=0.3,
        totalMass=0.05,
    )
    scene.Modelling.addChild(beam)
    FixedBox(applyTo=beam, atPositions=[1.0, 11.0, 11.0, -1.0, -1.0, -1.0])  # max corner first
    cable = PullingCable(
        beam,
        cableGeometry=[[x, 8.0, 5.0] for x in (10.0, 20.0, 30.0, 40.0, 50.0, 60.0)],
        pullPointLocation=[0.0, 8.0, 5.0],
    )
    rootNode.addObject(CableController(name="controller", cable=cable.CableConstraint))
    scene.Simulation.addChild(scene.Modelling)
    return rootNode
