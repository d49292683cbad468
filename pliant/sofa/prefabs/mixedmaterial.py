"""STLIB3's ``stlib3.physics.mixedmaterial.Rigidify``, written for Pliant from its
documentation: groups of a deformable body's nodes made rigid, each moving with one frame.

STLIB builds, under a new child of `targetObject`, the nodes ``DeformableParts`` (the body's
other nodes), ``RigidParts`` (a Rigid3 ``dofs`` with one frame per group) and, below it,
``RigidifiedParticules`` (the groups' nodes, carried by the frames through a RigidMapping);
the body's node loses its own solvers and becomes the child of both, its ``dofs`` gathered from
them by a SubsetMultiMapping. Pliant builds the same nodes and components. SOFA's frames are
placed from the body's positions when the prefab runs; Pliant, which reads the mesh only when
it builds the model, keeps the frames as given (``frames``, Pliant's data on the frames'
MechanicalObject) and the groups' nodes in order (``rigidified``, on the SubsetMultiMapping),
and :mod:`pliant.sofa.loader` places the frames where STLIB does (see there for what the frames
become in Pliant's model).
"""

from __future__ import annotations

from pliant.sofa.tree import SceneError, SceneNode

# The sizes of a frame STLIB accepts: Euler angles (degrees), a quaternion (x y z w), a
# position and Euler angles, a position and a quaternion.
FRAME_SIZES = (3, 4, 6, 7)


def Rigidify(  # noqa: N802 (STLIB's name)
    targetObject: SceneNode,  # noqa: N803
    sourceObject: SceneNode,  # noqa: N803
    groupIndices,  # noqa: N803
    frames=None,
    name: str | None = None,
    frameOrientation=None,  # noqa: N803 (STLIB's deprecated name of `frames`)
) -> SceneNode:
    """Make each group of `groupIndices` (node indices of `sourceObject`'s body) rigid, moving
    with its frame of `frames` (3 or 4 values: an orientation, the frame at the group's
    barycentre; 6 or 7: a position, then the orientation); returns the new node `name` (by
    default the source's name) holding ``DeformableParts`` and ``RigidParts``."""
    if frames is None:
        frames = frameOrientation
    groups = [[int(i) for i in group] for group in groupIndices]
    if frames is None:
        frames = [[0.0, 0.0, 0.0]] * len(groups)
    frames = [[float(v) for v in frame] for frame in frames]
    where = f"Rigidify (on {sourceObject.path})"
    if not groups or any(not group for group in groups):
        raise SceneError(
            f"{where}.groupIndices: one non-empty group of node indices per frame (a ROI's"
            " indices are computed when the script calls its init())"
        )
    if len(frames) != len(groups):
        raise SceneError(
            f"{where}.frames: {len(frames)} frames for {len(groups)} groups (one each)"
        )
    bad = [len(f) for f in frames if len(f) not in FRAME_SIZES]
    if bad:
        raise SceneError(
            f"{where}.frames: a frame has 3, 4, 6 or 7 values (orientation, position and"
            f" orientation), got {bad[0]}"
        )
    selected = [i for group in groups for i in group]
    if len(set(selected)) != len(selected):
        raise SceneError(f"{where}.groupIndices: a node belongs to two groups")
    holder = targetObject.addChild(name if name is not None else str(sourceObject.name))
    free = holder.addChild("DeformableParts")
    free.addObject("MechanicalObject", template="Vec3", name="dofs")
    rigid = holder.addChild("RigidParts")
    rigid.addObject(
        "MechanicalObject", template="Rigid3", name="dofs", reserve=len(frames), frames=frames
    )
    carried = rigid.addChild("RigidifiedParticules")
    carried.addObject("MechanicalObject", template="Vec3", name="dofs")
    carried.addObject(
        "RigidMapping",
        name="mapping",
        globalToLocalCoords=True,
        rigidIndexPerPoint=[j for j, group in enumerate(groups) for _ in group],
    )
    for own in ("solver", "integration", "correction"):
        found = sourceObject.getObject(own)
        if found is not None:
            sourceObject.removeObject(found)
    dofs = sourceObject.getMechanicalState()
    sourceObject.addObject(
        "SubsetMultiMapping",
        name="mapping",
        template="Vec3,Vec3",
        # from the body's node, where it ends (under DeformableParts): links that hold
        # wherever the scene moves the whole
        input=["@../dofs", "@../../RigidParts/RigidifiedParticules/dofs"],
        output=dofs.getLinkPath() if dofs is not None else "",
        rigidified=selected,
    )
    # SOFA's body node is then the child of both; Pliant's tree keeps it under the last.
    carried.addChild(sourceObject)
    free.addChild(sourceObject)
    return holder
