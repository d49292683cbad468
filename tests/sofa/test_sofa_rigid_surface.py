"""A rigid body of a SOFA scene touching a deformable body's TriangleCollisionModel
(pliant.constraints.surface.RigidSurfaceContact, built by the loader): a rigid ball dropped on
a soft block that collides by triangles only comes to rest on it, carrying its weight."""

from __future__ import annotations

from pathlib import Path

import meshio
import numpy as np
import pytest

from pliant.constraints import RigidSurfaceContact
from pliant.mesh import box_beam
from pliant.sofa import load_scene

SCENE = Path(__file__).parent / "sofa_scenes" / "ball_on_block.py"
G = 9810.0


@pytest.fixture(scope="module")
def block(tmp_path_factory) -> Path:
    """The block (12 x 12 x 4 mm) as a volume mesh and its surface mesh."""
    folder = tmp_path_factory.mktemp("ball_on_block")
    mesh = box_beam(12.0, 12.0, 4.0, nx=3, ny=3, nz=1)
    meshio.write(folder / "block.vtu", meshio.Mesh(mesh.points, [("tetra", mesh.tets)]))
    used, local = np.unique(mesh.boundary_triangles(), return_inverse=True)
    surface = meshio.Mesh(mesh.points[used], [("triangle", local.reshape(-1, 3))])
    meshio.write(folder / "block.stl", surface, binary=True)
    return folder


@pytest.mark.parametrize("massless", [False, True])
def test_rigid_ball_rests_on_a_block_touched_by_its_triangles(block, massless) -> None:
    """Also on a massless block held by rest-shape springs (SofaGym's BubbleMotion board)."""
    scene = load_scene(SCENE, mesh_dirs=[block], config={"massless": massless})
    assert scene.model.body.massless == massless
    contacts = scene.model.contacts
    (surface,) = contacts.rigid_surfaces
    assert isinstance(surface, RigidSurfaceContact)
    assert surface.body is scene.model.rigid_bodies[0] and surface.distance == 2.01
    solver, state = scene.solver(), scene.model.rest_state()
    for _ in range(100):
        state = solver.step(state)
    weight = 2e-4 * G
    keys, forces = state.contact_forces.keys, state.contact_forces.forces
    on = keys[:, 1] == 1 + len(contacts.shapes) + len(contacts.bodies)
    np.testing.assert_allclose(forces[on, 2].sum(), weight, rtol=1e-4)
    assert np.abs(state.rigid_velocities).max() < 1e-2
    found = surface.detect_rigid(
        state.positions, 1.0, 0, state.rigid_positions[0], state.rigid_rotations[0]
    )
    assert found[0].gap.min() > -contacts.tolerance


CART = Path(__file__).parent / "sofa_scenes" / "cart_goal.py"


def test_a_goal_carried_by_a_cart_on_a_rail(block) -> None:
    """SOFA's default MechanicalObject (one point at the origin, then its translation), the
    points of a RigidMapping child written from the rigid body's frame each step, and a
    PartialFixedConstraint holding the body to its x translation (CatchTheObject's cart)."""
    scene = load_scene(CART, mesh_dirs=[block])
    (cart,) = scene.model.rigid_bodies
    np.testing.assert_array_equal(cart.held, [False] + [True] * 5)
    goal, marker = scene.root.cart.Goal.GoalMO, scene.root.Marker.dofs
    np.testing.assert_allclose(marker.position.value, [[1.0, 2.0, 3.0]])
    # Turned 90 degrees about z: the offset (3, 2, 1) points along (-2, 3, 1).
    np.testing.assert_allclose(goal.position.value, [[-2.0, 3.0, 11.0]], atol=1e-12)
    solver, state, h = scene.solver(), scene.model.rest_state(), 0.01
    for k in range(1, 11):
        state = solver.step(state)
        scene.write_outputs(state)  # as after each step of a scene with controllers
        x = 1000.0 * h * h * k * (k + 1) / 2.0  # symplectic Euler under the x pull
        np.testing.assert_allclose(state.rigid_positions[0], [x, 0.0, 10.0], atol=1e-9)
        np.testing.assert_allclose(state.rigid_velocities[0], [1000.0 * h * k, 0.0, 0.0])
        np.testing.assert_allclose(goal.position.value, [[x - 2.0, 3.0, 11.0]], atol=1e-9)
    np.testing.assert_allclose(state.rigid_angular_velocities[0], 0.0, atol=0.0)
    np.testing.assert_allclose(marker.position.value, [[1.0, 2.0, 3.0]])
