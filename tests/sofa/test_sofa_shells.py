"""SOFA's TriangleFEMForceField read as a shell of triangles (pliant.sofa.shells): the scene's
law, nodes and mass, its steps equal to those of the body built with Pliant's API, a shell
joined beside a body of tetrahedra moving exactly as alone, and the refusals."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import run_scene

from pliant.diff.step import check_model
from pliant.errors import ModelError, ReductionError
from pliant.fem.shell import PlaneStress, ShellBody
from pliant.model import Model
from pliant.reduction import mesh_fingerprint
from pliant.sofa import SceneError, load_scene
from pliant.solvers import ImplicitEuler

SCENE = Path(__file__).parent / "sofa_scenes" / "shell_cube.py"
STEPS = 3


@pytest.fixture(scope="module")
def alone():
    scene = load_scene(SCENE)
    return scene, run_scene(scene, STEPS)


def test_scene_reads_the_shell(alone) -> None:
    """The cube's corners scaled by 10 and moved up by 10 (the MechanicalObject's transform
    on its topology's positions), its 12 triangles, the law (E, nu, thickness, method), the
    UniformMass spread over the 8 nodes and the bottom face held."""
    scene, _ = alone
    body = scene.model.body
    assert isinstance(body, ShellBody) and body.triangles.shape == (12, 3)
    assert body.material == PlaneStress(400.0, 0.3, thickness=0.5, method="large")
    assert np.ptp(body.rest_positions, axis=0) == pytest.approx([20.0, 20.0, 20.0])
    assert body.rest_positions[:, 1].min() == pytest.approx(0.0)
    np.testing.assert_allclose(body.node_masses, 0.01 / 8)
    np.testing.assert_array_equal(body.fixed_nodes, [0, 1, 2, 3])


@pytest.mark.parametrize("method", ["large", "small"])
def test_scene_steps_as_the_api_body(alone, method) -> None:
    """The scene's steps equal those of the ShellBody built with the API to round-off; the
    top face sinks under its weight (by 0.06 mm in three steps) and the held face stays."""
    scene, state = alone
    if method == "small":
        scene = load_scene(SCENE, config={"method": "small"})
        state = run_scene(scene, STEPS)
    body = scene.model.body
    api = ShellBody(
        body.rest_positions,
        body.triangles,
        PlaneStress(400.0, 0.3, thickness=0.5, method=method),
        total_mass=0.01,
        mass="uniform",
        fixed_nodes=[0, 1, 2, 3],
        gravity=(0.0, -9810.0, 0.0),
    )
    model = Model(api)
    expected = model.rest_state()
    for _ in range(STEPS):
        expected = ImplicitEuler(model, 0.01).step(expected)
    np.testing.assert_allclose(state.positions, expected.positions, atol=1e-12)
    sink = body.rest_positions[4:, 1] - state.positions[4:, 1]
    assert np.all(sink > 0.01) and np.all(sink < 1.0)
    np.testing.assert_array_equal(state.positions[:4], body.rest_positions[:4])


def test_shell_beside_a_beam_moves_as_alone(alone) -> None:
    """Joined with a cantilever of tetrahedra (one Pliant body, the shell's triangles acting
    on the union's nodes as a membrane), the cube's nodes end where the cube alone ends."""
    _, state = alone
    scene = load_scene(SCENE, config={"beam": True})
    joined = run_scene(scene, STEPS)
    assert scene.model.body.n_nodes == 8 + 16
    np.testing.assert_allclose(joined.positions[:8], state.positions, atol=1e-12)
    beam = joined.positions[8:] - scene.model.body.rest_positions[8:]
    assert np.abs(beam[:, 1]).max() > 1e-3  # the beam sags too
    # What cannot take a shell names it: model reduction and pliant.diff.
    with pytest.raises(ReductionError, match="shell of triangles"):
        mesh_fingerprint(scene.model.body)
    with pytest.raises(ModelError, match="membranes"):
        check_model(scene.model)
    with pytest.raises(ModelError, match="tetrahedra"):
        mesh_fingerprint(alone[0].model.body)


def test_shell_and_beam_touch_by_points_against_triangles() -> None:
    """With collision models on both, the cube's nodes meet the beam's surface and the beam's
    nodes the cube's triangles (SOFA tests the two models against each other both ways)."""
    scene = load_scene(SCENE, config={"beam": True, "contact": True})
    names = sorted(s.name for s in scene.model.contacts.surfaces)
    assert names == ["root/Beam on root/Cube", "root/Cube on root/Beam"]
    state = run_scene(scene, 1)
    assert np.all(np.isfinite(state.positions))


@pytest.mark.parametrize(
    ("config", "words"),
    [
        ({"plane_strain": True}, "planeStrain"),
        ({"method": "polar"}, "method 'polar'"),
        ({"beam": True, "cube_damping": 0.1}, "damped otherwise"),
        ({"carried": True}, "points carried by a shell"),
    ],
)
def test_refusals(config, words) -> None:
    with pytest.raises(SceneError, match=words):
        load_scene(SCENE, config=config)
