"""Instruments deployed through an entry, written for Pliant's tests in the form of SofaGym's
CatheterBeam (SOFA's BeamAdapter plugin): WireRestShapes, a combined instrument of `nodes`
Rigid3 nodes driven by an InterventionalRadiologyController, entering at the origin along z
(startingPos turns x onto z), no gravity. The configuration:

    instruments: a list of rest shapes, each a dict of WireRestShape's data (length,
        straightLength, spireDiameter, spireHeight, densityOfBeams, youngModulus,
        youngModulusExtremity) and radius, massDensity;
    xtip, rotation, speed: the controller's xtip, rotationInstrument and speed (default 0);
    tip_force: a ConstantForceField (fx fy fz mx my mz) on the last node (default none);
    nodes: the combined instrument's nodes (default 30);
    wall: z where a static square wall (two triangles, 100 wide, tilted 45 degrees about y)
        crosses the entry's axis, with SOFA's collision pipeline (default none).
"""

STRAIGHT = {
    "length": 100.0,
    "straightLength": 100.0,
    "densityOfBeams": [20],
    "youngModulus": 1.0e4,
    "youngModulusExtremity": 1.0e4,
    "radius": 1.0,
    "massDensity": 1.0e-6,
}


def createScene(root, config=None):
    config = {"instruments": [STRAIGHT], "xtip": [1.0], "rotation": [0.0], "nodes": 30} | dict(
        config or {}
    )
    root.gravity = [0.0, 0.0, 0.0]
    root.dt = 0.01
    root.addObject("RequiredPlugin", name="BeamAdapter")
    root.addObject("DefaultAnimationLoop")
    names = []
    for i, shape in enumerate(config["instruments"]):
        topology = root.addChild(f"topoLines_{i}")
        data = {k: v for k, v in shape.items() if k not in ("radius", "massDensity")}
        topology.addObject("WireRestShape", name="RestShape", template="Rigid3d", **data)
        topology.addObject("EdgeSetTopologyContainer", name="meshLines")
        topology.addObject("MechanicalObject", template="Rigid3d", name="dofTopo")
    instrument = root.addChild("InstrumentCombined")
    instrument.addObject("EulerImplicitSolver", rayleighStiffness=0.02, rayleighMass=0.0)
    instrument.addObject("BTDLinearSolver")
    instrument.addObject("RegularGridTopology", name="grid", nx=config["nodes"], ny=1, nz=1)
    instrument.addObject("MechanicalObject", template="Rigid3d", name="DOFs")
    for i, shape in enumerate(config["instruments"]):
        names.append(f"Interpol{i}")
        instrument.addObject(
            "WireBeamInterpolation",
            name=f"Interpol{i}",
            WireRestShape=f"@../topoLines_{i}/RestShape",
            radius=shape["radius"],
        )
        instrument.addObject(
            "AdaptiveBeamForceFieldAndMass",
            name=f"ForceField{i}",
            interpolation=f"@Interpol{i}",
            massDensity=shape["massDensity"],
        )
    instrument.addObject(
        "InterventionalRadiologyController",
        template="Rigid3d",
        name="controller",
        instruments=names,
        xtip=config["xtip"],
        rotationInstrument=config["rotation"],
        startingPos=[0, 0, 0, 0, -0.7071068, 0, 0.7071068],
        speed=config.get("speed", 0.0),
        controlledInstrument=0,
    )
    instrument.addObject("FixedConstraint", name="FixedConstraint", indices=0)
    instrument.addObject(
        "RestShapeSpringsForceField",
        points="@controller.indexFirstNode",
        stiffness=1e8,
        angularStiffness=1e8,
    )
    if config.get("wall") is not None:
        root.addObject("DefaultPipeline")
        root.addObject("BruteForceBroadPhase")
        root.addObject("BVHNarrowPhase")
        root.addObject("LocalMinDistance", alarmDistance=2.0, contactDistance=0.5)
        root.addObject("DefaultContactManager", response="FrictionContactConstraint")
        collis = instrument.addChild("Collis")
        collis.addObject("EdgeSetTopologyContainer", name="collisEdgeSet")
        collis.addObject("MechanicalObject", name="CollisionDOFs")
        collis.addObject("MultiAdaptiveBeamMapping", controller="../controller", useCurvAbs=True)
        collis.addObject("LineCollisionModel", group=1)
        collis.addObject("PointCollisionModel", group=1)
        z = config["wall"]
        wall = root.addChild("Wall")
        corners = [[-50.0, -50.0, z - 50.0], [50.0, -50.0, z + 50.0]]
        corners += [[50.0, 50.0, z + 50.0], [-50.0, 50.0, z - 50.0]]
        wall.addObject("MeshTopology", position=corners, triangles=[[0, 2, 1], [0, 3, 2]])
        wall.addObject("MechanicalObject", name="DOFs")
        wall.addObject("TriangleCollisionModel", simulated=False, moving=False)
    if config.get("tip_force") is not None:
        instrument.addObject(
            "ConstantForceField", indices=[config["nodes"] - 1], forces=[config["tip_force"]]
        )
    return root
