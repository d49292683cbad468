"""Two deformable bodies of a SOFA scene touching each other (pliant.sofa.bodies.surface_pairs,
pliant.constraints.surface): a soft cube resting on a soft block carries its weight on it."""

from __future__ import annotations

from pathlib import Path

import meshio
import numpy as np
import pytest

from pliant.constraints import SurfaceContact
from pliant.mesh import box_beam
from pliant.sofa import SceneError, load_scene

SCENE = Path(__file__).parent / "sofa_scenes" / "cube_on_block.py"
G = 9810.0


@pytest.fixture(scope="module")
def meshes(tmp_path_factory) -> Path:
    """The block (12 x 12 x 4 mm) and the cube (6 mm, 0.05 mm above the block's centre), as
    volume meshes and as surface meshes for the collision models."""
    folder = tmp_path_factory.mktemp("cube_on_block")
    block = box_beam(12.0, 12.0, 4.0, nx=3, ny=3, nz=1)
    cube = box_beam(6.0, 6.0, 6.0, nx=2, ny=2, nz=2, origin=(3.0, 3.0, 4.05))
    for name, mesh in (("block", block), ("cube", cube)):
        meshio.write(folder / f"{name}.vtu", meshio.Mesh(mesh.points, [("tetra", mesh.tets)]))
        faces = mesh.boundary_triangles()
        used, local = np.unique(faces, return_inverse=True)
        surface = meshio.Mesh(mesh.points[used], [("triangle", local.reshape(-1, 3))])
        meshio.write(folder / f"{name}.stl", surface, binary=True)
    return folder


def _rest(folder: Path, steps: int = 100, **config):
    scene = load_scene(SCENE, mesh_dirs=[folder], config=config or None)
    solver, state = scene.solver(), scene.model.rest_state()
    for _ in range(steps):
        state = solver.step(state)
    return scene, state


@pytest.mark.parametrize("own", [False, True])
def test_soft_cube_rests_on_a_soft_block(meshes, own) -> None:
    """Each body's points against the other's triangles (both ways, SOFA's pairs); at rest the
    contact forces hold the cube's weight (m g, to the contact tolerance), the cube has not
    sunk into the block, and nothing moves."""
    scene, state = _rest(meshes, own=own)
    surfaces = scene.model.contacts.surfaces
    assert len(surfaces) == 2 and all(isinstance(s, SurfaceContact) for s in surfaces)
    assert scene.model.contacts.shapes == []
    # Pair s is numbered 1 + s (after no obstacle, rigid body or plane); each force is the
    # one on the pair's points: up on the cube's, down on the block's.
    names = [s.name for s in surfaces]
    cube_on_block = 1 + names.index(
        "root/Cube/Collision on root/Block/Collision" if not own else "root/Cube on root/Block"
    )
    keys, forces = state.contact_forces.keys, state.contact_forces.forces
    carried = (
        forces[keys[:, 1] == cube_on_block, 2].sum() - forces[keys[:, 1] != cube_on_block, 2].sum()
    )
    np.testing.assert_allclose(carried, 0.001 * G, rtol=1e-4)
    assert np.abs(state.velocities).max() < 1e-3
    rows = scene.model.contacts.constraint(state.positions, None)
    assert rows.contacts.gap.min() > -0.01 - 1e-5  # the contact distance, to the tolerance


def test_bodies_in_one_group_do_not_touch(meshes) -> None:
    scene = load_scene(SCENE, mesh_dirs=[meshes], config={"groups": {"block": 1, "cube": 1}})
    assert scene.model.contacts is None


def test_bodies_touching_by_points_only_are_refused(tmp_path, meshes) -> None:
    """Points against points (no triangles on either body): SOFA tests them, Pliant has no
    such contact between deformable bodies."""
    text = SCENE.read_text().replace(
        '    models.addObject("TriangleCollisionModel", **extra)\n', ""
    )
    scene = tmp_path / "points_only.py"
    scene.write_text(text)
    with pytest.raises(SceneError, match="not by points of one against triangles"):
        load_scene(scene, mesh_dirs=[meshes])
