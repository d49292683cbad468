"""A cable-driven finger written, for the tests, as SofaGym writes its environments' scenes:
``createScene(rootNode, config, mode)`` reading the environment's configuration, SofaGym's
``addHeader`` / ``addVisu``, a goal node that the effector's goal links to, and the reward,
goal and action controllers of the scene's own toolbox module added to the root; a first
command (``config["action"]``) starts as an animation over one environment step
(``scale_factor`` steps)."""

import os
import pathlib
import sys

sys.path.insert(0, str(pathlib.Path(__file__).parent.absolute()))

from GymFingerToolbox import applyAction, goalSetter, rewardShaper, startCmd  # noqa: E402
from sofagym.header import addHeader, addVisu  # noqa: E402

path = os.path.dirname(os.path.abspath(__file__)) + "/mesh/"


def createScene(
    rootNode,
    config={  # noqa: B006 (SofaGym's scenes take their default configuration so)
        "dt": 0.01,
        "goalPos": [58.0, 12.0, 5.0],
        "youngModulus": 500.0,
        "action": 0,
        "scale_factor": 5,
        "source": [30.0, 0.0, 200.0],
        "target": [30.0, 0.0, 0.0],
        "zFar": 500,
    },
    mode="simu_and_visu",
):
    addHeader(
        rootNode,
        alarmDistance=1.0,
        contactDistance=0.5,
        gravity=[0.0, -9810.0, 0.0],
        dt=config["dt"],
        mu="0.3",
    )
    if "visu" in mode:
        addVisu(rootNode, config, position=[[30.0, 0.0, 200.0]], direction=[[0.0, 0.0, -1.0]])
        rootNode.addObject("BackgroundSetting", color=[1.0, 1.0, 1.0, 1.0])

    goal = rootNode.addChild("Goal")
    goal_mo = goal.addObject("MechanicalObject", name="GoalMO", position=config["goalPos"])

    finger = rootNode.addChild("Finger")
    finger.addObject("EulerImplicitSolver", rayleighMass=0.1, rayleighStiffness=0.1)
    finger.addObject("SparseLDLSolver", name="solver")
    finger.addObject("MeshVTKLoader", name="loader", filename=path + "beam.vtu")
    finger.addObject("TetrahedronSetTopologyContainer", src="@loader", name="container")
    finger.addObject("MechanicalObject", name="dofs", template="Vec3")
    finger.addObject("UniformMass", totalMass=0.05)
    finger.addObject(
        "TetrahedronFEMForceField",
        method="large",
        youngModulus=config["youngModulus"],
        poissonRatio=0.3,
    )
    finger.addObject("BoxROI", name="clamp", box=[-1.0, -1.0, -1.0, 1.0, 11.0, 11.0])
    finger.addObject("FixedConstraint", indices="@clamp.indices")
    finger.addObject("GenericConstraintCorrection", linearSolver="@solver")

    cable = finger.addChild("cable")
    cable.addObject(
        "MechanicalObject",
        name="meca",
        position=[[x, 8.0, 5.0] for x in (10.0, 20.0, 30.0, 40.0, 50.0, 60.0)],
    )
    cable.addObject(
        "CableConstraint",
        name="cable",
        indices=list(range(6)),
        pullPoint=[0.0, 8.0, 5.0],
        valueType="displacement",
        value=0.0,
    )
    cable.addObject("BarycentricMapping", mapForces=False, mapMasses=False)

    effector = finger.addChild("Effector")
    effector.addObject("MechanicalObject", name="tipMO", position=[[60.0, 5.0, 5.0]])
    effector.addObject("PositionEffector", indices=[0], effectorGoal="@../../Goal/GoalMO.position")
    effector.addObject("BarycentricMapping", mapForces=False, mapMasses=False)

    rootNode.finger = finger  # SofaGym's toolboxes reach the robot through the root
    rootNode.addObject(rewardShaper(name="Reward", rootNode=rootNode, goalPos=config["goalPos"]))
    rootNode.addObject(goalSetter(name="GoalSetter", goalMO=goal_mo, goalPos=config["goalPos"]))
    rootNode.addObject(applyAction(name="applyAction", root=rootNode))
    if config.get("action") is not None:  # a first command, started by the scene itself
        startCmd(rootNode, config["action"], config["scale_factor"] * config["dt"])
    return rootNode
