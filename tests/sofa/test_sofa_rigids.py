"""Rigid bodies in SOFA scenes (pliant.sofa.rigids): STLIB's Sphere falling onto its Floor
(free fall, then rest), SofaGym's addRigidObject (a ball given by a mesh and a density: its mass
and inertia), and a block pushing a ball, against the same model built with Pliant's API."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import meshio
import numpy as np
import pytest
from conftest import ball_surface

from pliant.constraints.base import EmbeddedPoints
from pliant.constraints.contact import Contacts
from pliant.fem.body import TetBody
from pliant.fem.loads import NodalForces
from pliant.fem.material import Corotational
from pliant.fem.rigid import RigidBody
from pliant.geometry.collision import Box, Plane, Sphere, TriangleMesh
from pliant.geometry.inertia import box_inertia, mesh_mass
from pliant.mesh import box_beam
from pliant.model import Model
from pliant.sofa import SceneError, load_scene
from pliant.sofa.rigids import PARTICLE_INERTIA, mesh_shape
from pliant.sofa.tree import SceneNode
from pliant.solvers import ImplicitEuler

SCENES = Path(__file__).parent / "sofa_scenes"
G, DT = 9810.0, 0.01
BALL_CENTRE, BALL_RADIUS, DENSITY = np.array([1.0, 2.0, 3.0]), 5.0, 2e-6


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    """A 10 mm block (held by its base in the scenes) and ball.obj (radius 5, 400 vertices,
    centred off its file's origin), with the SofaGym scene beside them (it reads its mesh
    while the script runs, from its folder)."""
    path = tmp_path_factory.mktemp("rigids")
    block = box_beam(10.0, 10.0, 10.0, 2, 2, 2)
    meshio.write(path / "block.vtu", meshio.Mesh(block.points, [("tetra", block.tets)]))
    vertices, faces = ball_surface(400, BALL_RADIUS, BALL_CENTRE)
    lines = [f"v {x!r} {y!r} {z!r}" for x, y, z in vertices.tolist()]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in faces]
    (path / "ball.obj").write_text("\n".join(lines) + "\n")
    shutil.copy(SCENES / "rigid_mesh_ball.py", path)
    return path


def test_a_sphere_falls_freely_then_rests_on_the_floor(folder) -> None:
    """STLIB's Sphere (radius uniformScale = 5, vertexMass from totalMass and inertiaMatrix)
    dropped from z = 20 onto the Floor at z = 0: before contact its height is the closed form
    of the step, z_n = z_0 - g h^2 n (n + 1) / 2 (symplectic Euler), within g h t / 2 of free
    fall's z_0 - g t^2 / 2; then it rests at the radius above the floor. The still Sphere
    (isAStaticObject) is a sphere obstacle at its translation."""
    scene = load_scene(SCENES / "rigid_ball_drop.py", mesh_dirs=[folder])
    (ball,) = scene.model.rigid_bodies
    assert isinstance(ball.shape, Sphere) and ball.shape.radius == 5.0
    assert ball.mass == 0.01
    np.testing.assert_allclose(ball.inertia, 0.1 * np.eye(3))
    floor, still = scene.model.contacts.shapes
    assert isinstance(floor, Plane) and isinstance(still, Sphere)
    assert still.radius == 3.0
    np.testing.assert_allclose(still.position, [5.0, 5.0, 14.0])
    solver, state = scene.solver(), scene.model.rest_state()
    heights = []
    for _ in range(30):
        state = solver.step(state)
        heights.append(state.rigid_positions[0, 2])
    n = np.arange(1, 6)  # z_5 = 5.285: still above the floor by the radius
    np.testing.assert_allclose(heights[:5], 20.0 - G * DT**2 * n * (n + 1) / 2, rtol=0, atol=1e-9)
    t = n * DT
    assert np.all(np.abs(heights[:5] - (20.0 - G * t**2 / 2)) <= G * DT * t / 2 + 1e-9)
    assert heights[-1] == pytest.approx(5.0, abs=1e-6)  # radius + floor
    np.testing.assert_allclose(state.rigid_positions[0, :2], [40.0, 5.0], atol=1e-9)
    assert np.abs(state.rigid_velocities[0]).max() < 1e-6


def test_a_ball_given_by_a_mesh_and_a_density_has_the_solid_sphere_mass(folder) -> None:
    """SofaGym's addRigidObject: GenerateRigidMass gives the mass and inertia of the solid the
    mesh bounds (here its inscribed polyhedron: 1.4 % under the sphere's 4/3 pi r^3 rho with
    400 vertices, its inertia 2.4 % under 2/5 m r^2), and the collision mesh is shifted so that
    its centre of mass is the rigid frame's origin (the file's ball is centred at (1, 2, 3))."""
    scene = load_scene(folder / "rigid_mesh_ball.py", mesh_dirs=[folder])
    (ball,) = scene.model.rigid_bodies
    assert isinstance(ball.shape, TriangleMesh)
    vertices, faces = ball_surface(400, BALL_RADIUS, BALL_CENTRE)
    solid = mesh_mass(vertices, faces, DENSITY)
    assert ball.mass == pytest.approx(solid.mass, rel=1e-12)
    np.testing.assert_allclose(ball.inertia, solid.inertia, rtol=1e-10, atol=1e-16)
    sphere_mass = 4.0 / 3.0 * np.pi * BALL_RADIUS**3 * DENSITY
    assert -0.02 < ball.mass / sphere_mass - 1.0 < 0.0  # the inscribed polyhedron
    np.testing.assert_allclose(
        np.diag(ball.inertia) / (0.4 * sphere_mass * BALL_RADIUS**2), 1.0, atol=0.03
    )
    assert np.abs(ball.inertia - np.diag(np.diag(ball.inertia))).max() < 1e-3 * ball.inertia[0, 0]
    np.testing.assert_allclose(ball.position, [40.0, 5.0, 20.0])
    shifted = mesh_mass(ball.shape.vertices, ball.shape.faces)
    np.testing.assert_allclose(shifted.centre, 0.0, atol=1e-9)
    generator = scene.root.Ball.getObject("mass")
    np.testing.assert_allclose(generator.massCenter.value, BALL_CENTRE, atol=1e-2)
    np.testing.assert_allclose(generator.centerToOrigin.value, -solid.centre, atol=1e-12)


def test_a_block_pushes_a_ball_as_the_api_model_does(folder) -> None:
    """block_pushes_ball.py: a block held by its base and pushed up by a ConstantForceField
    carries a Rigid3 ball (a SphereCollisionModel on its own node) lying 0.5 mm above its top;
    the same block, floor and ball built with Pliant's API step to the same positions and
    poses to round-off."""
    scene = load_scene(SCENES / "block_pushes_ball.py", mesh_dirs=[folder])
    by_scene = [scene.model.rest_state()]
    solver = scene.solver()
    for _ in range(8):
        by_scene.append(solver.step(by_scene[-1]))

    mesh = box_beam(10.0, 10.0, 10.0, 2, 2, 2)
    body = TetBody(
        mesh,
        Corotational(50.0, 0.3, "large", inversion="tolerate"),
        fixed_nodes=np.flatnonzero(mesh.points[:, 2] <= 0.1),
        frame_nodes=mesh.tets[:, :3],
        loads=[NodalForces(np.arange(mesh.n_nodes), [0.0, 0.0, 10.0])],
        gravity=(0.0, 0.0, -G),
        mass="uniform",
        total_mass=0.01,
    )
    ball = RigidBody(
        Sphere(4.0, position=[5.0, 5.0, 14.5]), 0.002, 0.002 * 6.4 * np.eye(3), friction=0.2
    )
    points = EmbeddedPoints(mesh, body.rest_positions, tolerance=body.extent, outside="keep")
    floor = Plane(normal=(0.0, 0.0, 1.0), point=(-50.0, -50.0, 0.0))
    contacts = Contacts([floor], friction=0.2, margin=1.0, points=points, thickness=0.1)
    model = Model(body, contacts=contacts, rigid_bodies=[ball])
    by_api = [model.rest_state()]
    api_solver = ImplicitEuler(model, DT, tangent="fresh")
    for _ in range(8):
        by_api.append(api_solver.step(by_api[-1]))
    lift = by_api[-1].rigid_positions[0, 2] - 14.5
    assert lift < -0.2 and by_api[-1].positions[:, 2].max() > 10.1  # fell on it; block pushed up
    for a, b in zip(by_scene, by_api, strict=True):
        np.testing.assert_allclose(a.positions, b.positions, rtol=0, atol=1e-9)
        np.testing.assert_allclose(a.rigid_positions, b.rigid_positions, rtol=0, atol=1e-9)
        np.testing.assert_allclose(a.rigid_rotations, b.rigid_rotations, rtol=0, atol=1e-9)


def test_a_rigid_body_needs_a_mass(folder, tmp_path) -> None:
    """A moving Rigid3 ball with no UniformMass: one SceneError naming its node."""
    text = (SCENES / "block_pushes_ball.py").read_text()
    massless = re.sub(r'ball\.addObject\(\s*"UniformMass",', "dict(", text)
    assert massless != text
    (tmp_path / "massless.py").write_text(massless)
    with pytest.raises(SceneError, match="root/Ball: a rigid body needs a mass"):
        load_scene(tmp_path / "massless.py", mesh_dirs=[folder])


def test_a_particle_ball_is_a_rigid_sphere_that_does_not_turn(folder) -> None:
    """particle_ball.py: the Vec3 ball (totalMass 1e-4, radius 2) is a rigid sphere whose
    inertia is PARTICLE_INERTIA times a solid ball's (SOFA does not turn a particle); it lands
    on the floor at its radius and its position is written back to its MechanicalObject; the
    goal marker, with no solver nor mass, is a still sphere obstacle."""
    scene = load_scene(SCENES / "particle_ball.py", mesh_dirs=[folder])
    (ball,) = scene.model.rigid_bodies
    assert isinstance(ball.shape, Sphere) and ball.shape.radius == 2.0 and ball.mass == 1e-4
    np.testing.assert_allclose(ball.inertia, PARTICLE_INERTIA * 0.4 * 1e-4 * 4.0 * np.eye(3))
    floor, goal = scene.model.contacts.shapes
    assert isinstance(goal, Sphere) and goal.radius == 1.5
    np.testing.assert_allclose(goal.position, [-20.0, 0.0, 3.0])
    state = scene.simulate(12)
    assert state.rigid_positions[0, 2] == pytest.approx(2.0, abs=1e-6)
    scene.write_outputs(state)
    written = scene.root.Ball.ball_mo.position.value
    np.testing.assert_allclose(written, state.rigid_positions[:1], rtol=0, atol=0)


def test_a_script_renames_a_component_and_a_node() -> None:
    """SofaGym's ``obj.name.value = "RigidBaseMO"``: the component (and a node) renamed, found
    under the new name."""
    root = SceneNode("root")
    cart = root.addChild("Cart")
    dofs = cart.addObject("MechanicalObject", template="Rigid3")
    dofs.name.value = "RigidBaseMO"
    cart.name.value = "Carriage"
    assert root.Carriage is cart and cart.RigidBaseMO is dofs
    assert dofs.getPathName() == "/Carriage/RigidBaseMO"


def test_collision_points_without_a_closed_surface_take_their_convex_hull() -> None:
    """A rigid body's collision points with no triangles (a PointCollisionModel on a ball's
    vertices, as BubbleMotion's ball) or with an open surface: the closed mesh of their convex
    hull, faces outwards (its volume, the polyhedron's, is positive)."""
    vertices, faces = ball_surface(200, 3.0)
    for given in (None, faces[:-1]):  # no triangles; one missing: open
        shape = mesh_shape(vertices, given, "ball")
        assert isinstance(shape, TriangleMesh) and len(shape.faces) == len(faces)
        assert shape.volume == pytest.approx(mesh_mass(vertices, faces).volume, rel=1e-12)
    with pytest.raises(SceneError, match="bound no solid"):
        mesh_shape(np.eye(3), None, "flat")


def test_a_cart_on_sofas_shared_cube_is_a_box(folder, tmp_path) -> None:
    """addRigidObject on SOFA's shared mesh/cube.obj (corners at +-1), scaled as SofaGym's
    carts are and turned by its quaternion: a Box of half extents `scale`, mass 8 sx sy sz
    rho and the box's inertia (GenerateRigidMass: the solid the cube bounds)."""
    scene = tmp_path / "cart.py"
    scene.write_text(
        (folder / "rigid_mesh_ball.py")
        .read_text()
        .replace('filename="ball.obj"', 'filename="mesh/cube.obj", scale=[2.0, 1.0, 3.0]')
        .replace("0.0, 0.0, 0.0, 1.0]", "0.0, -0.7071068, 0.0, 0.7071068]")
    )
    shutil.copy(folder / "block.vtu", tmp_path)
    (cart,) = load_scene(scene).model.rigid_bodies
    assert isinstance(cart.shape, Box)
    np.testing.assert_allclose(cart.shape.half_extents, [2.0, 1.0, 3.0])
    mass = 8.0 * 6.0 * DENSITY
    assert cart.mass == pytest.approx(mass, rel=1e-12)
    np.testing.assert_allclose(cart.inertia, box_inertia(mass, [2.0, 1.0, 3.0]), atol=1e-12 * mass)
    np.testing.assert_allclose(cart.rotation @ [1.0, 0.0, 0.0], [0.0, 0.0, 1.0], atol=1e-6)
