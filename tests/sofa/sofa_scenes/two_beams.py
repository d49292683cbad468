"""Two cantilevers side by side in one scene, written for Pliant's tests: beam A (E = 500,
0.05 kg, held by a FixedConstraint on a BoxROI, pulled by a cable in displacement) and beam B
(E = 1500, 0.2 kg, held by RestShapeSpringsForceField, pulled by a cable in force), 30 mm apart
along z, each with its own EulerImplicitSolver. The configuration picks which beams the scene
holds, and variants that Pliant refuses or that add a floor both beams may touch:

    bodies: "AB" (default), "A" or "B";
    damping_b, mass_damping_b: beam B's rayleighStiffness and rayleighMass (A's are 0.1);
    law_b: "corotational" (default) or "neohookean" (B's FEM);
    static_b: beam B under a StaticSolver;
    floor: collision models on both beams (group ``floor_groups``) and a floor below them.
"""

BEAMS = {
    # name: (translation, Young's modulus, total mass)
    "A": ([0.0, 0.0, 0.0], 500.0, 0.05),
    "B": ([0.0, 0.0, 30.0], 1500.0, 0.2),
}


def _beam(root, name, config):
    shift, young, mass = BEAMS[name]
    node = root.addChild(name)
    damping = config.get("damping_b", 0.1) if name == "B" else 0.1
    mass_damping = config.get("mass_damping_b", 0.1) if name == "B" else 0.1
    if name == "B" and config.get("static_b"):
        node.addObject("StaticSolver")
    else:
        node.addObject("EulerImplicitSolver", rayleighMass=mass_damping, rayleighStiffness=damping)
    node.addObject("SparseLDLSolver")
    node.addObject("MeshVTKLoader", name="loader", filename="beam.vtu", translation=shift)
    node.addObject("MeshTopology", src="@loader", name="topology")
    node.addObject("MechanicalObject", name="dofs", template="Vec3")
    node.addObject("UniformMass", totalMass=mass)
    if name == "B" and config.get("law_b") == "neohookean":
        node.addObject(
            "TetrahedronHyperelasticityFEMForceField",
            materialName="NeoHookean",
            ParameterSet="500 1000",
        )
    else:
        node.addObject("TetrahedronFEMForceField", youngModulus=young, poissonRatio=0.3)
    box = [-1.0, -1.0, shift[2] - 1.0, 1.0, 11.0, shift[2] + 11.0]
    node.addObject("BoxROI", name="held", box=box)
    if name == "A":
        node.addObject("FixedConstraint", indices="@held.indices")
    else:
        node.addObject("RestShapeSpringsForceField", points="@held.indices", stiffness=1e10)
    node.addObject("LinearSolverConstraintCorrection")
    cable = node.addChild("cable")
    points = [[x, 8.0, shift[2] + 5.0] for x in (10.0, 20.0, 30.0, 40.0, 50.0, 60.0)]
    cable.addObject("MechanicalObject", position=points)
    if name == "A":
        cable.addObject(
            "CableConstraint",
            indices=list(range(6)),
            pullPoint=[0.0, 8.0, 5.0],
            valueType="displacement",
            value=1.5,
        )
    else:
        cable.addObject(
            "CableConstraint",
            indices=list(range(6)),
            pullPoint=[0.0, 8.0, 35.0],
            valueType="force",
            value=20.0,
        )
    cable.addObject("BarycentricMapping")
    if config.get("floor"):
        collision = node.addChild("collision")
        collision.addObject("MeshTopology", src="@../loader")
        collision.addObject("MechanicalObject", src="@../loader")
        collision.addObject("PointCollisionModel", group=config["floor_groups"][name])
        collision.addObject("BarycentricMapping")
    return node


def createScene(rootNode, config=None):
    config = config or {}
    rootNode.dt = 0.01
    rootNode.gravity = [0.0, -9810.0, 0.0]
    rootNode.addObject("FreeMotionAnimationLoop")
    rootNode.addObject("GenericConstraintSolver", tolerance=1e-12, maxIterations=1000)
    if config.get("floor"):
        rootNode.addObject("CollisionPipeline")
        rootNode.addObject("BruteForceBroadPhase")
        rootNode.addObject("BVHNarrowPhase")
        rootNode.addObject("CollisionResponse", response="FrictionContactConstraint")
        rootNode.addObject("LocalMinDistance", alarmDistance=3.0, contactDistance=0.1)
        floor = rootNode.addChild("floor")
        corners = [[-10, -3, -10], [80, -3, -10], [80, -3, 50], [-10, -3, 50]]
        floor.addObject("MeshTopology", position=corners, triangles=[0, 2, 1, 0, 3, 2])
        floor.addObject("MechanicalObject", position=corners)
        floor.addObject("TriangleCollisionModel", moving=False, simulated=False, group=9)
    for name in config.get("bodies", "AB"):
        _beam(rootNode, name, config)
    return rootNode
