"""SOFA's reduced-order models read as the full model they reduce (pliant.sofa.reduced), and
a membrane of triangles on a body's nodes (a TriangleFEMForceField in a child node)."""

from __future__ import annotations

from pathlib import Path

import meshio
import numpy as np
import pytest

from pliant.fem.body import TetBody, nodes_in_box
from pliant.fem.material import Corotational
from pliant.fem.shell import PlaneStress, TriangleFEM
from pliant.mesh import box_beam
from pliant.model import Model
from pliant.sofa import SceneError, load_scene
from pliant.sofa.reduced import ReducedOrderWarning
from pliant.sofa.shells import tet_faces
from pliant.solvers import ImplicitEuler

SCENES = Path(__file__).parent / "sofa_scenes"


@pytest.fixture(scope="module")
def beam(tmp_path_factory):
    folder = tmp_path_factory.mktemp("reduced")
    mesh = box_beam(60.0, 10.0, 10.0, 6, 2, 2)
    meshio.write(folder / "beam.vtu", meshio.Mesh(mesh.points, [("tetra", mesh.tets)]))
    return mesh, folder


def _load(folder, **config):
    with pytest.warns(ReducedOrderWarning, match="read as the full model"):
        return load_scene(SCENES / "reduced_beam.py", mesh_dirs=[folder], config=config or None)


def _run(solver, state, steps=4):
    for _ in range(steps):
        state = solver.step(state)
    return state


def test_a_reduced_scene_is_its_full_model_with_the_membrane_on_its_nodes(beam) -> None:
    """The reduced cantilever steps as the full beam built with Pliant's API, its top face's
    triangles a TriangleFEM membrane on the beam's nodes, to round-off; the membrane stiffens
    it (the tip sags less); the mode amplitudes stay readable (their first values)."""
    mesh, folder = beam
    scene = _load(folder)
    assert scene.model.body.n_elements == mesh.n_tets
    alpha = scene.root.solverNode.reducedModel.alpha.position.value
    np.testing.assert_array_equal(np.ravel(alpha), [0.0, 0.0])
    by_scene = _run(scene.solver(), scene.model.rest_state())

    top = np.zeros(mesh.n_nodes, dtype=bool)
    top[nodes_in_box(mesh.points, np.array([[-1.0, 9.9, -1.0], [61.0, 10.1, 11.0]]))] = True
    faces = tet_faces(mesh.tets)
    faces = faces[top[faces].all(axis=1)]
    assert len(faces) == 2 * 6 * 2  # the top face's triangles, two a grid cell

    def body(membranes):
        return TetBody(
            mesh,
            Corotational(500.0, 0.3, "large"),
            mass="uniform",
            total_mass=0.05,
            fixed_nodes=nodes_in_box(mesh.points, np.array([[-1.0, -1.0, -1.0], [1, 11, 11]])),
            frame_nodes=mesh.tets[:, :3],
            gravity=(0.0, -9810.0, 0.0),
            rayleigh_mass=0.1,
            rayleigh_stiffness=0.1,
            membranes=membranes,
        )

    layer = TriangleFEM(mesh.points, faces, PlaneStress(5000.0, 0.45, method="large"))
    model = Model(body([layer]))
    api = _run(ImplicitEuler(model, 0.01, tangent="fresh"), model.rest_state())
    assert np.abs(by_scene.positions - api.positions).max() < 1e-9

    bare = _load(folder, membrane=False)
    free = _run(bare.solver(), bare.model.rest_state())
    tip = np.argmax(mesh.points[:, 0] + mesh.points[:, 1])
    sag = mesh.points[tip, 1] - free.positions.reshape(-1, 3)[tip, 1]
    held = mesh.points[tip, 1] - by_scene.positions.reshape(-1, 3)[tip, 1]
    assert sag > 0.1 and held < 0.9 * sag


def test_a_membrane_needs_triangles_of_the_body(beam, tmp_path) -> None:
    """A membrane layer whose triangles name no BoxROI's trianglesInROI is one SceneError."""
    _, folder = beam
    text = (
        (SCENES / "reduced_beam.py")
        .read_text()
        .replace('triangles="@top.trianglesInROI"', 'triangles="@top.indices"')
    )
    (tmp_path / "bad_membrane.py").write_text(text)
    with pytest.warns(ReducedOrderWarning), pytest.raises(SceneError, match="trianglesInROI"):
        load_scene(tmp_path / "bad_membrane.py", mesh_dirs=[folder])
