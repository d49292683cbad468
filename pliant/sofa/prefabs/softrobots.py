"""SoftRobots' actuator prefabs (``softrobots.actuators``), written for Pliant from their
documentation: a cable pulled through points carried by its parent body, and a cavity under
pressure or volume growth whose surface mesh the parent body carries."""

from __future__ import annotations

from pliant.sofa.prefabs.stlib import _loader_for
from pliant.sofa.tree import SceneError, SceneNode


def PullingCable(  # noqa: N802 (SoftRobots' name)
    attachedTo: SceneNode | None = None,  # noqa: N803
    name: str = "Cable",
    cableGeometry=((1.0, 0.0, 0.0), (0.0, 0.0, 0.0)),  # noqa: N803
    rotation=(0.0, 0.0, 0.0),
    translation=(0.0, 0.0, 0.0),
    uniformScale: float = 1.0,  # noqa: N803
    pullPointLocation=None,  # noqa: N803
    initialValue: float = 0.0,  # noqa: N803
    valueType: str = "displacement",  # noqa: N803
) -> SceneNode:
    """A child `name` of `attachedTo`: the cable's points (placed by rotation, translation
    and scale), a CableConstraint through all of them (pulled from `pullPointLocation`, else
    from its first point) with `initialValue` in `valueType`, mapped onto the parent."""
    cable = attachedTo.addChild(name)
    cable.addObject(
        "MechanicalObject",
        position=[list(p) for p in cableGeometry],
        rotation=list(rotation),
        translation=list(translation),
        scale=uniformScale,
    )
    pull = {"hasPullPoint": False}
    if pullPointLocation is not None:
        pull = {"pullPoint": list(pullPointLocation), "hasPullPoint": True}
    cable.addObject(
        "CableConstraint",
        indices=list(range(len(cableGeometry))),
        value=initialValue,
        valueType=valueType,
        **pull,
    )
    cable.addObject("BarycentricMapping", name="Mapping", mapForces=False, mapMasses=False)
    return cable


def PneumaticCavity(  # noqa: N802
    surfaceMeshFileName: str | None = None,  # noqa: N803
    attachedAsAChildOf: SceneNode | None = None,  # noqa: N803
    attachedTo: SceneNode | None = None,  # noqa: N803
    name: str = "PneumaticCavity",
    rotation=(0.0, 0.0, 0.0),
    translation=(0.0, 0.0, 0.0),
    uniformScale: float = 1.0,  # noqa: N803
    initialValue: float = 0.0,  # noqa: N803
    valueType: str = "volumeGrowth",  # noqa: N803
) -> SceneNode:
    """A cavity: its surface mesh (STL or OBJ), a SurfacePressureConstraint with
    `initialValue` as `valueType` ("volumeGrowth" by default, or "pressure"), mapped onto
    the body; in `attachedTo` itself, or in a new child `name` of `attachedAsAChildOf`."""
    if surfaceMeshFileName is None or (attachedTo is None) == (attachedAsAChildOf is None):
        raise SceneError(
            "PneumaticCavity needs a surfaceMeshFileName and one of attachedTo, attachedAsAChildOf"
        )
    node = attachedTo if attachedTo is not None else attachedAsAChildOf.addChild(name)
    node.addObject(
        _loader_for(surfaceMeshFileName),
        name="MeshLoader",
        filename=surfaceMeshFileName,
        rotation=list(rotation),
        translation=list(translation),
        scale=uniformScale,
    )
    node.addObject("MeshTopology", name="topology", src="@MeshLoader")
    node.addObject("MechanicalObject", src="@topology")
    node.addObject("SurfacePressureConstraint", value=initialValue, valueType=valueType)
    node.addObject("BarycentricMapping", name="Mapping", mapForces=False, mapMasses=False)
    return node
