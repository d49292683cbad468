"""Collision triangles carried by STLIB's Rigidify frame (SofaGym's Maze: the maze on the
Tripod's free centre): a scene written for this test, a block clamped at both ends whose top
middle is rigidified on a free frame (a Rigid3 ``FreeCenter`` mapped into Rigidify's frames, as
the Tripod writes it), a closed box of triangles carried by that frame and a particle ball
resting on it. The frame is a rigid body whose shape is the box (its inside read from its
winding number); the ball's contact acts back on the frame and so on the block."""

from __future__ import annotations

import meshio
import numpy as np
import pytest

from pliant.geometry.collision import Sphere, TriangleMesh
from pliant.mesh import box_beam
from pliant.sofa import load_scene

PLATE = """
import Sofa
from stlib3.physics.deformable import ElasticMaterialObject
from stlib3.physics.mixedmaterial import Rigidify
from stlib3.scene import MainHeader, ContactHeader
from stlib3.components import addOrientedBoxRoi


def createScene(root):
    MainHeader(root, gravity=[0.0, -9810.0, 0.0], dt=0.01)
    ContactHeader(root, alarmDistance=0.5, contactDistance=0.2, frictionCoef=0.2)
    root.addObject("FreeMotionAnimationLoop")
    root.addObject("GenericConstraintSolver", maxIterations=1000, tolerance=1e-8)
    simulation = root.addChild("Simulation")
    simulation.addObject("EulerImplicitSolver")
    simulation.addObject("SparseLDLSolver")
    simulation.addObject("GenericConstraintCorrection")
    block = ElasticMaterialObject(volumeMeshFileName="block.vtu", name="Block", totalMass=0.01,
                                  youngModulus=1000.0, poissonRatio=0.3)
    modelling = root.addChild("Modelling")
    modelling.addChild(block)
    block.dofs.init()
    block.addObject("PointCollisionModel")
    points = [list(p) for p in block.dofs.rest_position.value]
    for name, x in (("left", 0), ("right", 40)):
        ends = addOrientedBoxRoi(block, position=points, name=name, translation=[x, 5, 5],
                                 scale=[2, 12, 12])
        ends.init()
        block.addObject("FixedConstraint", name=name + "Fixed", indices=ends.indices.value)
    top = block.addObject("SphereROI", name="top", centers=[20, 10, 5], radii=[6])
    top.init()
    rigid = Rigidify(modelling, block, groupIndices=[list(top.indices.value)],
                     frames=[[20, 10, 5, 0, 0, 0, 1]], name="Mixed")
    simulation.addChild(rigid)
    centre = rigid.addChild("FreeCenter")
    centre.addObject("MechanicalObject", name="dofs", template="Rigid3",
                     position=[20, 10, 5, 0, 0, 0, 1])
    centre.addChild(rigid.RigidParts)
    rigid.RigidParts.addObject("SubsetMultiMapping", input=[centre.getLinkPath()],
                               output="@./", indexPairs=[0, 0])
    plate = centre.addChild("Plate")
    plate.addObject("MeshTopology", triangles={triangles})
    plate.addObject("MechanicalObject", name="plate", position={corners})
    plate.addObject("TriangleCollisionModel")
    plate.addObject("RigidMapping", index=0)
    ball = simulation.addChild("Ball")
    ball.addObject("MechanicalObject", name="ball_mo", position=[21.0, 13.0, 5.5])
    ball.addObject("UniformMass", totalMass=1e-4)
    ball.addObject("SphereCollisionModel", radius=2)
"""
# The plate: a box 12 x 1 x 8 in the frame, 0.5 above the frame's origin (the block's top).
LOW, HIGH = np.array([-6.0, 0.5, -4.0]), np.array([6.0, 1.5, 4.0])
BOX_FACES = [
    [0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7], [0, 1, 5], [0, 5, 4],
    [2, 3, 7], [2, 7, 6], [1, 2, 6], [1, 6, 5], [0, 4, 7], [0, 7, 3],
]  # fmt: skip


@pytest.fixture(scope="module")
def plate_scene(tmp_path_factory):
    folder = tmp_path_factory.mktemp("carried")
    mesh = box_beam(40.0, 10.0, 10.0, 8, 2, 2)
    meshio.write(folder / "block.vtu", meshio.Mesh(mesh.points, [("tetra", mesh.tets)]))
    unit = np.array([[0, 0, 0], [1, 0, 0], [1, 0, 1], [0, 0, 1]], dtype=float)
    corners = np.vstack([unit, unit + [0, 1, 0]]) * (HIGH - LOW) + LOW
    text = PLATE.format(triangles=BOX_FACES, corners=corners.tolist())
    (folder / "plate.py").write_text(text)
    scene = load_scene(folder / "plate.py")
    return scene, scene.simulate(40)


def test_a_mesh_on_a_free_rigidified_frame_is_that_frame_s_shape(plate_scene) -> None:
    scene, _ = plate_scene
    ball, frame = scene.model.rigid_bodies
    assert isinstance(ball.shape, Sphere) and isinstance(frame.shape, TriangleMesh)
    assert frame.shape.winding
    np.testing.assert_allclose(frame.position, [20.0, 10.0, 5.0])
    np.testing.assert_allclose(frame.shape.vertices.min(axis=0), LOW)
    np.testing.assert_allclose(frame.shape.vertices.max(axis=0), HIGH)


def test_a_ball_rests_on_the_carried_mesh_and_weighs_on_the_body(plate_scene) -> None:
    """After 40 steps the ball sits on the plate at its radius (no penetration beyond the
    contact solver's tolerance), at rest, its weight carried by its contacts (to the solver's
    tolerance: the ball jitters at 1e-4 mm/s); the plate and the
    block's middle have sunk under it and the frame's weight (both ends clamped)."""
    scene, state = plate_scene
    ball, frame = scene.model.rigid_bodies
    x_ball, x_frame, r_frame = (
        state.rigid_positions[0],
        state.rigid_positions[1],
        state.rigid_rotations[1],
    )
    frame.shape.set_pose(x_frame, r_frame)
    gap = frame.shape.signed_distance(x_ball[None]).gap[0] - ball.shape.radius
    assert abs(gap) < 1e-5
    assert np.abs(state.rigid_velocities[0]).max() < 1e-3
    assert x_frame[1] < 10.0 - 1e-3  # the frame moves with the block, which sags
    weight = ball.mass * 9810.0
    normal = state.contact_forces.forces.sum(axis=0)[1]
    assert normal == pytest.approx(weight, rel=1e-4)  # the contact solver's tolerance
