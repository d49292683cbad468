"""A BeamAdapter beam written for Pliant's tests in the form of SofaGym's StemPendulum: a
Rigid3 MechanicalObject of N + 1 frames along x from the origin on an EdgeSetTopologyContainer
(length 10, circular section of radius 0.2, E = 3e6), a BeamInterpolation and an
AdaptiveBeamForceFieldAndMass. The configuration picks its supports and loads:

    frames: N (default 10);
    base: "clamp" (a FixedConstraint on frame 0) or "hinge" (a PartialFixedConstraint that
        leaves the rotation about z free, with a RestShapeSpringsForceField of angular
        stiffness `spring` on frame 0, as the StemPendulum's);
    spring: the hinge's angular stiffness (default 300);
    tip_force: a ConstantForceField on the tip frame (fx fy fz mx my mz) (default none);
    base_torque: a ConstantForceField on frame 0 with this moment about z (default none);
    density: the AdaptiveBeamForceFieldAndMass's massDensity (default 1e-2); None: no mass
        (computeMass=False);
    tip_mass: a UniformMass of this totalMass on the tip frame (default none);
    gravity: the root's gravity (default 0 -981 0);
    straight, rotation: the BeamInterpolation's straight flag and the MechanicalObject's
        rotation (default True and none);
    mass_index: the UniformMass's index (default the tip's);
    young: the BeamInterpolation's defaultYoungModulus (default 3e6).
"""

import Sofa.Core

LENGTH, RADIUS, YOUNG = 10.0, 0.2, 3.0e6


class Torque(Sofa.Core.Controller):
    """Sets the base's moment about z before each step, as SofaGym's applyAction does."""

    def __init__(self, *args, **kwargs):
        Sofa.Core.Controller.__init__(self, *args, **kwargs)
        self.field, self.value = kwargs["field"], kwargs["value"]

    def onAnimateBeginEvent(self, event):
        force = self.field.force.value.tolist()
        force[5] = self.value
        self.field.force.value = force


def createScene(rootNode, config=None):
    config = {"frames": 10, "base": "clamp", "spring": 300.0, "density": 1e-2} | dict(config or {})
    n = config["frames"]
    rootNode.gravity = config.get("gravity", [0.0, -981.0, 0.0])
    rootNode.dt = config.get("dt", 0.01)
    rootNode.addObject("RequiredPlugin", pluginName="BeamAdapter")
    rootNode.addObject("DefaultAnimationLoop")
    rootNode.addObject("VisualStyle", displayFlags="showBehaviorModels")
    beam = rootNode.addChild("Beam")
    beam.addObject("EulerImplicitSolver", rayleighStiffness=0.0, rayleighMass=0.0)
    beam.addObject("SparseLDLSolver", name="solver")
    positions = [[LENGTH * i / n, 0.0, 0.0] for i in range(n + 1)]
    beam.addObject(
        "EdgeSetTopologyContainer", position=positions, edges=[[i, i + 1] for i in range(n)]
    )
    beam.addObject(
        "MechanicalObject",
        template="Rigid3",
        position=[p + [0.0, 0.0, 0.0, 1.0] for p in positions],
        rotation=config.get("rotation", [0.0, 0.0, 0.0]),
    )
    beam.addObject(
        "BeamInterpolation",
        radius=RADIUS,
        defaultYoungModulus=config.get("young", YOUNG),
        straight=config.get("straight", True),
    )
    if config["density"] is None:
        beam.addObject("AdaptiveBeamForceFieldAndMass", computeMass=False)
    else:
        beam.addObject("AdaptiveBeamForceFieldAndMass", massDensity=config["density"])
    if config.get("tip_mass"):
        beam.addObject(
            "UniformMass", indices=[config.get("mass_index", n)], totalMass=config["tip_mass"]
        )
    if config["base"] == "clamp":
        beam.addObject("FixedConstraint", indices=[0])
    else:
        beam.addObject("PartialFixedConstraint", indices=[0], fixedDirections=[1, 1, 1, 1, 1, 0])
        beam.addObject(
            "RestShapeSpringsForceField",
            stiffness=0,
            angularStiffness=config["spring"],
            points=0,
            template="Rigid3d",
        )
    if config.get("tip_force") is not None:
        beam.addObject("ConstantForceField", name="tip", indices=[n], forces=[config["tip_force"]])
    if config.get("base_torque") is not None:
        field = beam.addObject("ConstantForceField", name="base", indices=[0], totalForce=[0] * 6)
        rootNode.addObject(Torque(name="torque", field=field, value=config["base_torque"]))
    tip = beam.addChild("Tip")
    tip.addObject("MechanicalObject", position=[[0.0, 0.5, 0.0]])
    tip.addObject("RigidMapping", index=n)
    return rootNode
