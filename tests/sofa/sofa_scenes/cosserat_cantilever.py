"""A Cosserat cantilever written for Pliant's tests in SofaGym's form: a rod of SOFA's
Cosserat plugin built by ``sofagym.utils.createCosserat`` along x from the origin (length 100,
circular section of radius 1, E = 2e5), its base clamped by a FixedConstraint on the rigid
base (beside createCosserat's springs). The configuration picks the load and the
discretisation:

    sections, frames: nbSectionS and nbFramesF (default 10 and 10);
    tip_force: a ConstantForceField on the tip frame, (fx fy fz mx my mz) (default none);
    mass: a UniformMass (totalMass) on the frames, under the root's gravity (default none);
    gravity: the root's gravity (default 0 0 -9810).
"""

from sofagym.utils import createCosserat

LENGTH, RADIUS, YOUNG = 100.0, 1.0, 2.0e5


def createScene(rootNode, config=None):
    config = {"sections": 10, "frames": 10, "gravity": [0.0, 0.0, -9810.0]} | dict(config or {})
    rootNode.gravity = config["gravity"]
    rootNode.dt = 0.01
    rootNode.addObject("RequiredPlugin", pluginName="Cosserat")
    rootNode.addObject("DefaultAnimationLoop")
    rod = createCosserat(
        rootNode,
        {
            "init_pos": [0.0, 0.0, 0.0],
            "tot_length": LENGTH,
            "nbSectionS": config["sections"],
            "nbFramesF": config["frames"],
        },
        name="Rod",
        radius=RADIUS,
        youngModulus=YOUNG,
    )
    rod.rigidBase.addObject("FixedConstraint", indices=0)
    frames = rod.rigidBase.MappedFrames
    if config.get("tip_force") is not None:
        tip = config["frames"] + 1
        frames.addObject("ConstantForceField", indices=[tip], forces=[config["tip_force"]])
    if config.get("mass"):
        frames.addObject("UniformMass", totalMass=config["mass"])
    return rootNode
