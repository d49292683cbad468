"""A cantilever written as a reduced-order scene of SOFA's ModelOrderReduction plugin (SofaGym's
MultiGait is one): mode amplitudes mapped onto the beam's MechanicalObject, hyper-reduced
force fields, a matrix mapper, and a membrane of triangles (a BoxROI's trianglesInROI on the
beam's top face) acting on the beam's nodes. Pliant reads it as the full model it reduces.
With ``config={"membrane": False}`` the membrane is left out."""

ECSW = {  # the reduction's files: not read by Pliant (none exists here)
    "prepareECSW": False,
    "performECSW": True,
    "nbModes": 2,
    "modesPath": "modes.txt",
    "RIDPath": "rid.txt",
    "weightsPath": "weights.txt",
    "nbTrainingSet": 10,
    "periodSaveGIE": 5,
}


def createScene(rootNode, config={"membrane": True}):  # noqa: B006 (SofaGym's signature)
    rootNode.dt = 0.01
    rootNode.gravity = [0.0, -9810.0, 0.0]
    rootNode.addObject("RequiredPlugin", name="ModelOrderReduction")
    rootNode.addObject("FreeMotionAnimationLoop")
    rootNode.addObject("GenericConstraintSolver", tolerance=1e-8, maxIterations=100)
    solver = rootNode.addChild("solverNode")
    solver.addObject("EulerImplicitSolver", rayleighStiffness=0.1, rayleighMass=0.1)
    solver.addObject("SparseLDLSolver", name="preconditioner")
    solver.addObject("GenericConstraintCorrection", solverName="preconditioner")
    solver.addObject(
        "MechanicalMatrixMapperMOR",
        template="Vec1d,Vec1d",
        object1="@./reducedModel/alpha",
        object2="@./reducedModel/alpha",
        nodeToParse="@./reducedModel/model",
        performECSW=True,
        listActiveNodesPath="active.txt",
    )
    reduced = solver.addChild("reducedModel")
    reduced.addObject("MechanicalObject", template="Vec1d", name="alpha", position=[0.0, 0.0])
    model = reduced.addChild("model")
    model.addObject("MeshVTKLoader", name="loader", filename="beam.vtu")
    model.addObject("TetrahedronSetTopologyContainer", src="@loader")
    model.addObject("MechanicalObject", name="tetras", template="Vec3d")
    model.addObject(
        "ModelOrderReductionMapping", input="@../alpha", output="@./tetras", modesPath="modes.txt"
    )
    model.addObject("UniformMass", totalMass=0.05)
    model.addObject(
        "HyperReducedTetrahedronFEMForceField",
        method="large",
        youngModulus=500.0,
        poissonRatio=0.3,
        **ECSW,
    )
    model.addObject("BoxROI", name="held", box=[-1.0, -1.0, -1.0, 1.0, 11.0, 11.0])
    model.addObject("FixedConstraint", indices="@held.indices")
    if config.get("membrane", True):
        model.addObject("BoxROI", name="top", box=[-1.0, 9.9, -1.0, 61.0, 10.1, 11.0])
        layer = model.addChild("membrane")
        layer.addObject(
            "TriangleSetTopologyContainer",
            position="@top.pointsInROI",
            triangles="@top.trianglesInROI",
        )
        layer.addObject(
            "HyperReducedTriangleFEMForceField",
            method="large",
            youngModulus=5000.0,
            poissonRatio=0.45,
            **ECSW,
        )
