"""STLIB3, SPLIB3 and SoftRobots' Python prefabs and SofaGym's scene helpers re-implemented
for Pliant, importable by the names scenes use (``stlib3.scene``, ``splib3.animation``,
``softrobots.actuators``, ``sofagym.header``, ...)
only while Pliant loads a scene script (:func:`prefab_modules`)."""

from __future__ import annotations

import math
import types

from pliant.sofa.prefabs import mixedmaterial, sofagym, softrobots, splib, stlib
from pliant.sofa.sofapython3 import Key, module


def prefab_modules() -> dict[str, types.ModuleType]:
    """The prefab modules by name (packages and their submodules), fresh for one scene."""
    splib.reset_animations()
    scene = {
        "Scene": stlib.Scene,
        "MainHeader": stlib.MainHeader,
        "ContactHeader": stlib.ContactHeader,
    }
    rigid = {k: getattr(stlib, k) for k in ("RigidObject", "Cube", "Floor", "Sphere")}
    animation = {
        "animate": splib.animate,
        "AnimationManager": splib.AnimationManager,
        "AnimationManagerController": splib.AnimationManagerController,
        "Animation": splib.Animation,
    }
    vec3 = {"Vec3": splib.Vec3, "vadd": splib.vadd, "vsub": splib.vsub}
    numerics = {  # SPLIB's numerics hold math's functions too
        **{k: v for k, v in vars(math).items() if not k.startswith("_")},
        "to_radians": splib.to_radians,
        "to_degrees": splib.to_degrees,
        "getOrientedBoxFromTransform": splib.getOrientedBoxFromTransform,
        "Quat": splib.Quat,
        "RigidDof": splib.RigidDof,
        **vec3,
    }
    keys = {k: v for k, v in vars(Key).items() if k[0] != "_"}
    members = {
        "stlib3": {},
        "stlib3.scene": scene,
        "stlib3.scene.mainheader": {"MainHeader": stlib.MainHeader},
        "stlib3.scene.contactheader": {"ContactHeader": stlib.ContactHeader},
        "stlib3.scene.scene": {"Scene": stlib.Scene},
        "stlib3.physics": {},
        "stlib3.physics.deformable": {"ElasticMaterialObject": stlib.ElasticMaterialObject},
        "stlib3.physics.rigid": rigid,
        "stlib3.physics.constraints": {"FixedBox": stlib.FixedBox},
        "stlib3.physics.mixedmaterial": {"Rigidify": mixedmaterial.Rigidify},
        "stlib3.physics.collision": {"CollisionMesh": stlib.CollisionMesh},
        "stlib3.visuals": {"VisualModel": stlib.VisualModel},
        "stlib3.solver": {"DefaultSolver": stlib.DefaultSolver},
        "stlib3.components": {"addOrientedBoxRoi": stlib.addOrientedBoxRoi},
        "splib3": {},
        "splib3.animation": animation,
        "splib3.animation.animate": animation,
        "splib3.animation.easing": {"LinearRamp": splib.LinearRamp},
        "splib3.numerics": numerics,
        "splib3.numerics.vec3": vec3,
        "splib3.numerics.quat": {"Quat": splib.Quat},
        "splib3.constants": {"Key": types.SimpleNamespace(**keys)},
        "splib3.constants.Key": keys,
        "splib3.objectmodel": {
            "setData": splib.setData,
            "SofaPrefab": splib.SofaPrefab,
            "SofaObject": splib.SofaObject,
        },
        "splib3.loaders": {
            "loadPointListFromFile": splib.loadPointListFromFile,
            "getLoadingLocation": splib.getLoadingLocation,
        },
        "sofagym": {},
        "sofagym.header": sofagym.header_members(),
        "sofagym.utils": sofagym.utils_members(),
        "softrobots": {},
        "softrobots.actuators": {
            "PullingCable": softrobots.PullingCable,
            "PneumaticCavity": softrobots.PneumaticCavity,
        },
    }
    modules = {name: module(name, dict(found)) for name, found in members.items()}
    for name, made in modules.items():
        parent, _, leaf = name.rpartition(".")
        if parent:  # the function wins over a module of the same name (splib3.animation)
            modules[parent].__dict__.setdefault(leaf, made)
    return modules
