"""Scenes with several deformable bodies (pliant.sofa.bodies): joined in one Pliant body over
the disjoint union of their meshes, each moving exactly as it moves alone; what cannot be
joined stops with one SceneError naming it."""

from __future__ import annotations

from pathlib import Path

import meshio
import numpy as np
import pytest
from conftest import run_scene

from pliant.constraints.base import EmbeddedPoints
from pliant.constraints.cable import CableActuator
from pliant.errors import ModelError
from pliant.fem.body import TetBody, nodes_in_box
from pliant.fem.loads import RestShapeSprings
from pliant.fem.material import Corotational
from pliant.mesh import box_beam
from pliant.mesh.tetmesh import TetMesh
from pliant.model import Model
from pliant.sofa import SceneError, load_scene
from pliant.solvers import ImplicitEuler

SCENE = Path(__file__).parent / "sofa_scenes" / "two_beams.py"
STEPS = 4


@pytest.fixture(scope="module")
def beam(tmp_path_factory) -> tuple[TetMesh, Path]:
    """The 60 x 10 x 10 beam both bodies load, and the folder holding it."""
    folder = tmp_path_factory.mktemp("two_beams")
    mesh = box_beam(60.0, 10.0, 10.0, 6, 2, 2)
    meshio.write(folder / "beam.vtu", meshio.Mesh(mesh.points, [("tetra", mesh.tets)]))
    return mesh, folder


def _load(folder: Path, **config):
    return load_scene(SCENE, mesh_dirs=[folder], config=config or None)


@pytest.fixture(scope="module")
def joined(beam):
    scene = _load(beam[1])
    return scene, run_scene(scene, STEPS)


def test_two_bodies_move_exactly_as_each_alone(beam, joined) -> None:
    """Beams A and B share nothing but the time step: the union's matrices are block
    diagonal, so each beam's nodes end where the beam alone ends, to round-off (measured
    1e-13 mm), after both moved by millimetres (A by its cable's displacement, B by its
    cable's force and its weight)."""
    scene, state = joined
    n = beam[0].n_nodes
    assert scene.model.body.n_nodes == 2 * n
    assert [a.name for a in scene.model.actuators] == ["A/cable", "B/cable"]
    rest = scene.model.body.rest_positions
    for rows, name in ((slice(0, n), "A"), (slice(n, 2 * n), "B")):
        alone = run_scene(_load(beam[1], bodies=name), STEPS)
        assert np.abs(alone.positions - rest[rows]).max() > 0.5
        assert np.abs(state.positions[rows] - alone.positions).max() < 1e-9
        assert np.abs(state.velocities[rows] - alone.velocities).max() < 1e-6


def test_bodies_of_different_damping_each_keep_their_own(beam) -> None:
    """Beam B damped far more than A (rayleighMass 2 and rayleighStiffness 0.5 against 0.1
    and 0.1), as SOFA damps each under its own EulerImplicitSolver: the joined body's beams
    end where each alone ends, to round-off, and B's damping slowed it."""
    config = {"damping_b": 0.5, "mass_damping_b": 2.0}
    scene = _load(beam[1], **config)
    assert scene.model.body.rayleigh_dofs() is not None
    state = run_scene(scene, STEPS)
    n = beam[0].n_nodes
    for rows, name in ((slice(0, n), "A"), (slice(n, 2 * n), "B")):
        alone = run_scene(_load(beam[1], bodies=name, **config), STEPS)
        assert np.abs(state.positions[rows] - alone.positions).max() < 1e-9
        assert np.abs(state.velocities[rows] - alone.velocities).max() < 1e-6
    lightly = run_scene(_load(beam[1], bodies="B"), STEPS)
    assert np.abs(lightly.velocities).max() > 1.05 * np.abs(state.velocities[n:]).max()


def test_two_bodies_as_built_with_the_api(beam, joined) -> None:
    """The same two beams built with Pliant's API (one TetBody over both meshes, B's
    elements stiffer, each beam's UniformMass on its own nodes, A held, B on springs, a cable
    on each) end at the scene's positions to round-off."""
    mesh, _ = beam
    n, m = mesh.n_nodes, mesh.tets.shape[0]
    points = np.vstack([mesh.points, mesh.points + [0.0, 0.0, 30.0]])
    tets = np.vstack([mesh.tets, mesh.tets + n])
    held = nodes_in_box(mesh.points, [[-1.0, -1.0, -1.0], [1.0, 11.0, 11.0]])
    body = TetBody(
        TetMesh(points, tets),
        Corotational(500.0, 0.3, "large", inversion="tolerate"),
        separate=True,
        mass="uniform",
        total_mass=0.25,
        frame_nodes=tets[:, :3],
        fixed_nodes=held,
        loads=[RestShapeSprings(held + n, points, 1e10)],
        gravity=(0.0, -9810.0, 0.0),
        rayleigh_mass=0.1,
        rayleigh_stiffness=0.1,
    )
    stiff = Corotational(1500.0, 0.3)
    body.mu[m:], body.lam[m:] = stiff.mu, stiff.lam
    body.set_node_masses(np.concatenate([np.full(n, 0.05 / n), np.full(n, 0.2 / n)]))
    cables = []
    for name, z, mode, value in (("A", 5.0, "displacement", 1.5), ("B", 35.0, "force", 20.0)):
        path = np.array([[x, 8.0, z] for x in (10.0, 20.0, 30.0, 40.0, 50.0, 60.0)])
        cables.append(
            CableActuator(
                EmbeddedPoints(TetMesh(points, tets), path, outside="keep"),
                points,
                pull_point=np.array([0.0, 8.0, z]),
                name=name,
                mode=mode,
                value=value,
                change_reference="lagged",
            )
        )
    model = Model(body, actuators=cables)
    solver, state = ImplicitEuler(model, 0.01, tangent="fresh"), model.rest_state()
    for _ in range(STEPS):
        state = solver.step(state)
    scene, by_scene = joined
    np.testing.assert_array_equal(scene.model.body.node_masses, body.node_masses)
    np.testing.assert_array_equal(scene.model.body.mu, body.mu)
    assert np.abs(by_scene.positions - state.positions).max() < 1e-9
    np.testing.assert_allclose(by_scene.actuation, state.actuation, rtol=1e-9)


def test_each_body_reads_and_writes_its_own_nodes(beam, joined) -> None:
    """Each MechanicalObject holds its body's rows of the state; positions a script sets on
    one body's data move that body's rows only."""
    scene, state = joined
    n = beam[0].n_nodes
    scene.write_outputs(state)
    a, b = (next(x for x in scene.root.walk() if x.name == k).dofs for k in "AB")
    np.testing.assert_array_equal(a.position.value, state.positions[:n])
    np.testing.assert_array_equal(b.position.value, state.positions[n:])
    b.attrs["position"] = scene.model.body.rest_positions[n:] + 1.0
    read = scene.read_inputs(state)
    np.testing.assert_array_equal(read.positions[:n], state.positions[:n])
    np.testing.assert_array_equal(read.positions[n:], scene.model.body.rest_positions[n:] + 1.0)


@pytest.mark.parametrize(
    ("config", "message"),
    [
        ({"law_b": "neohookean"}, "elements of different laws"),
        ({"static_b": True}, r"static and dynamic ODE solvers \(root/A: dynamic, root/B: static"),
        (
            {"floor": True, "floor_groups": {"A": 1, "B": 2}},
            "contact between deformable bodies, which SOFA tests: root/A and root/B",
        ),
    ],
)
def test_what_cannot_be_joined_is_named(beam, config, message) -> None:
    with pytest.raises(SceneError, match=message):
        _load(beam[1], **config)


def test_bodies_in_one_collision_group_touch_the_floor(beam) -> None:
    """Collision models that share a group do not collide (SOFA): each beam's points, found
    in its own mesh, touch the floor only; the floor holds both beams up."""
    scene = _load(beam[1], floor=True, floor_groups={"A": 1, "B": 1})
    n = beam[0].n_nodes
    points = scene.model.contacts.points
    assert len(points) == 2 * n
    rest = scene.model.body.rest_positions
    np.testing.assert_allclose(points.positions(rest), rest, atol=1e-9)
    state = run_scene(scene, 2)
    assert np.all(np.isfinite(state.positions))
    assert state.positions[:, 1].min() > -3.0 - 0.1 - 1e-3  # the floor, less the thickness


def test_node_masses_make_a_diagonal_mass_matrix(beam) -> None:
    body = TetBody(beam[0], Corotational(500.0, 0.3), mass="consistent", density=1e-6)
    with pytest.raises(ModelError, match="consistent"):
        body.set_node_masses(np.ones(beam[0].n_nodes))
    lumped = TetBody(beam[0], Corotational(500.0, 0.3), density=1e-6)
    with pytest.raises(ModelError, match="finite values > 0"):
        lumped.set_node_masses(np.zeros(beam[0].n_nodes))
