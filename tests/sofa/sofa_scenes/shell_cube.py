"""A shell cube of triangles (SOFA's TriangleFEMForceField), written for Pliant's tests: the
8 corners and 12 triangles of a cube of side 2, scaled by its MechanicalObject to 20 mm and
moved up by 10 mm, held by a FixedConstraint on its bottom face and pulled down by its weight
(0.01 kg, UniformMass), under its own EulerImplicitSolver. The configuration sets:

    method: the FEM's method, "large" (default) or "small";
    thickness: the FEM's thickness (default 0.5);
    plane_strain: SOFA's planeStrain flag (refused by Pliant);
    cube_damping: the cube's rayleighStiffness (default 0; the beam's is 0);
    carried: a child node of the cube with points mapped on it (refused by Pliant);
    beam: a cantilever of tetrahedra on a 4 x 2 x 2 grid beside the cube (its own solver);
    contact: with the beam, a collision pipeline and point and triangle models on both.
"""

CORNERS = [
    [1, -1, -1], [1, -1, 1], [-1, -1, 1], [-1, -1, -1],
    [1, 1, -1], [1, 1, 1], [-1, 1, 1], [-1, 1, -1],
]  # fmt: skip
TRIANGLES = [
    [0, 1, 2], [0, 2, 3], [4, 7, 6], [4, 6, 5], [0, 4, 5], [0, 5, 1],
    [1, 5, 6], [1, 6, 2], [2, 6, 7], [2, 7, 3], [4, 0, 3], [4, 3, 7],
]  # fmt: skip


def createScene(rootNode, config=None):
    config = config or {}
    rootNode.dt = 0.01
    rootNode.gravity = [0.0, -9810.0, 0.0]
    cube = rootNode.addChild("Cube")
    cube.addObject("EulerImplicitSolver", rayleighStiffness=config.get("cube_damping", 0.0))
    cube.addObject("SparseLDLSolver")
    cube.addObject("MeshTopology", name="topology", position=CORNERS, triangles=TRIANGLES)
    cube.addObject("MechanicalObject", name="dofs", scale=10.0, translation=[0.0, 10.0, 0.0])
    cube.addObject("UniformMass", totalMass=0.01)
    fem = {
        "youngModulus": 400.0,
        "poissonRatio": 0.3,
        "thickness": config.get("thickness", 0.5),
        "method": config.get("method", "large"),
    }
    if config.get("plane_strain"):
        fem["planeStrain"] = True
    cube.addObject("TriangleFEMForceField", **fem)
    cube.addObject("BoxROI", name="bottom", box=[-11.0, -1.0, -11.0, 11.0, 1.0, 11.0])
    cube.addObject("FixedConstraint", indices="@bottom.indices")
    if config.get("carried"):
        points = cube.addChild("points")
        points.addObject("MechanicalObject", position=[[0.0, 10.0, 0.0]])
        points.addObject("BarycentricMapping")
    if config.get("beam"):
        beam = rootNode.addChild("Beam")
        beam.addObject("EulerImplicitSolver")
        beam.addObject("SparseLDLSolver")
        beam.addObject("RegularGridTopology", n=[4, 2, 2], min=[30, 0, 0], max=[60, 10, 10])
        beam.addObject("MechanicalObject", name="dofs")
        beam.addObject("UniformMass", totalMass=0.02)
        beam.addObject("TetrahedronFEMForceField", youngModulus=500.0, poissonRatio=0.3)
        beam.addObject("BoxROI", name="held", box=[29.0, -1.0, -1.0, 31.0, 11.0, 11.0])
        beam.addObject("FixedConstraint", indices="@held.indices")
    if config.get("contact"):
        rootNode.addObject("DefaultPipeline")
        rootNode.addObject("BruteForceBroadPhase")
        rootNode.addObject("BVHNarrowPhase")
        rootNode.addObject("LocalMinDistance", alarmDistance=2.0, contactDistance=0.5)
        rootNode.addObject("DefaultContactManager", response="FrictionContactConstraint")
        for node in (cube, beam):
            node.addObject("TriangleCollisionModel")
            node.addObject("PointCollisionModel")
    return rootNode
