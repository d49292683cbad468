"""Run SOFA scenes in Pliant: a ``.scn`` XML scene or a SofaPython3 ``createScene`` script
(with STLIB3 / SPLIB3 / SoftRobots prefabs and Python controllers), read into a Pliant model
with SOFA's choices (docs/sofa.md).

    scene = load_scene("diamond.scn", mesh_dirs=["meshes"])
    state = scene.simulate(100)
"""

from pliant.sofa.loader import SofaScene, load_scene
from pliant.sofa.tree import SceneError, SceneNode, read_scene

__all__ = ["SceneError", "SceneNode", "SofaScene", "load_scene", "read_scene"]
