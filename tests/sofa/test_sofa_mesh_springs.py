"""SOFA's MeshSpringForceField on points a BarycentricMapping carries, with their UniformMass,
and ReadState (the body's state read from a WriteState file as the scene runs): a small scene
read by pliant.sofa steps as the same model built with Pliant's API, to round-off."""

from __future__ import annotations

import dataclasses

import meshio
import numpy as np
import pytest

from pliant.constraints.base import EmbeddedPoints
from pliant.fem.body import TetBody
from pliant.fem.loads import EmbeddedSprings
from pliant.fem.material import Corotational
from pliant.mesh import box_beam
from pliant.model import Model
from pliant.sofa import SceneError, load_scene
from pliant.solvers import ImplicitEuler

SCENE = """<Node name="root" dt="0.01" gravity="0 -9810 0">
<Node name="Body">
  <EulerImplicitSolver rayleighMass="0.1" rayleighStiffness="0.1"/>
  <SparseLDLSolver/>
  <MeshVTKLoader name="loader" filename="body.vtu"/>
  <MeshTopology src="@loader"/>
  <MechanicalObject name="dofs"/>
  <ReadState filename="state.txt" shift="0.01"/>
  <UniformMass totalMass="0.01"/>
  <TetrahedronFEMForceField youngModulus="1000" poissonRatio="0.3" method="large"/>
  <BoxROI name="clamp" box="-1 -1 -1 0.1 11 11"/>
  <FixedConstraint indices="@clamp.indices"/>
  <Node name="pipe">
    <EdgeSetTopologyContainer position="{points}" edges="0 1 1 2 2 3"/>
    <MechanicalObject/>
    <UniformMass totalMass="0.004"/>
    <MeshSpringForceField stiffness="{stiffness}" damping="{damping}"/>
    <BarycentricMapping/>
  </Node>
</Node></Node>"""
# The pull point (first) lies outside the beam, as a cable's does in SofaGym's TrunkCup.
POINTS = np.array([[41.0, 5.0, 5.0], [38.0, 2.0, 2.0], [20.0, 3.0, 3.0], [6.0, 2.0, 2.0]])
STIFFNESS = 50.0


@pytest.fixture(scope="module")
def beam(tmp_path_factory):
    folder = tmp_path_factory.mktemp("springs")
    mesh = box_beam(40.0, 10.0, 10.0, 4, 1, 1)
    meshio.write(folder / "body.vtu", meshio.Mesh(mesh.points, [("tetra", mesh.tets)]))
    rng = np.random.default_rng(1)
    first = mesh.points + rng.normal(scale=0.2, size=mesh.points.shape)
    first[mesh.points[:, 0] < 0.1] = mesh.points[mesh.points[:, 0] < 0.1]
    later = mesh.points + np.array([0.0, -0.5, 0.0]) * mesh.points[:, :1] / 40.0
    lines = ["T= 0.01", "  X= " + " ".join(f"{v:.17g}" for v in first.ravel())]
    lines += ["T= 0.03", "  X= " + " ".join(f"{v:.17g}" for v in later.ravel())]
    (folder / "state.txt").write_text("\n".join(lines) + "\n")
    return mesh, folder, first, later


def _scene(folder, damping: float = 0.0, edges: str = 'edges="0 1 1 2 2 3"'):
    text = SCENE.format(
        points=" ".join(f"{v:g}" for v in POINTS.ravel()), stiffness=STIFFNESS, damping=damping
    ).replace('edges="0 1 1 2 2 3"', edges)
    (folder / "springs.scn").write_text(text)
    return load_scene(folder / "springs.scn")


def _beam_body(mesh, total_mass: float, loads=()) -> TetBody:
    """The scene's beam as Pliant's API builds it (its x < 0.1 end held)."""
    return TetBody(
        mesh,
        Corotational(1000.0, 0.3, "large"),
        mass="uniform",
        total_mass=total_mass,
        fixed_nodes=np.flatnonzero(mesh.points[:, 0] < 0.1),
        gravity=(0.0, -9810.0, 0.0),
        rayleigh_mass=0.1,
        rayleigh_stiffness=0.1,
        loads=list(loads),
    )


def test_the_scene_steps_as_the_model_built_with_the_api(beam) -> None:
    """Three steps: the first starts from the record at T = 0.01 (shift 0.01), the third
    from the record at T = 0.03; the springs and the mapped mass as Pliant's API builds them
    (masses through the barycentric weights, HRZ-lumped), the same states to round-off."""
    mesh, folder, first, later = beam
    scene = _scene(folder)
    solver = scene.solver()
    states = [scene.model.rest_state()]
    for _ in range(3):
        states.append(solver.step(states[-1]))

    extent = float(np.linalg.norm(np.ptp(mesh.points, axis=0)))
    embedded = EmbeddedPoints(mesh, POINTS, tolerance=extent, outside="keep")
    rest = np.linalg.norm(np.diff(POINTS, axis=0), axis=1)
    springs = EmbeddedSprings(
        embedded.nodes, embedded.weights, [0, 1, 1, 2, 2, 3], STIFFNESS, rest_lengths=rest
    )
    body = _beam_body(mesh, 0.01, loads=[springs])
    carried = np.zeros(mesh.n_nodes)
    shares = embedded.weights**2 / (embedded.weights**2).sum(axis=1, keepdims=True)
    np.add.at(carried, embedded.nodes, 0.001 * shares)  # HRZ: positive, 0.001 per point
    body.set_node_masses(body.node_masses + carried)
    model = Model(body)
    api = ImplicitEuler(model, 0.01, tangent="fresh")
    state = dataclasses.replace(model.rest_state(), positions=first.copy())
    expected = [state]
    for step in range(3):
        if step == 2:
            state = dataclasses.replace(state, positions=later.copy())
        state = api.step(state)
        expected.append(state)
    assert np.isclose(scene.model.body.total_mass, 0.014)
    for got, want in zip(states[1:], expected[1:], strict=True):
        assert np.abs(got.positions - want.positions).max() < 1e-9
    # The springs move the body: without them the first step ends elsewhere.
    alone = Model(_beam_body(mesh, 0.014))
    start = dataclasses.replace(alone.rest_state(), positions=first.copy())
    free = ImplicitEuler(alone, 0.01, tangent="fresh").step(start)
    assert np.abs(free.positions - states[1].positions).max() > 1e-3


def test_spring_damping_cells_and_a_bad_state_file_are_refused(beam) -> None:
    mesh, folder, _, _ = beam
    with pytest.raises(SceneError, match="damping"):
        _scene(folder, damping=0.5)
    with pytest.raises(SceneError, match="edges of triangles too"):
        _scene(folder, edges='edges="0 1 1 2" triangles="0 1 2"')
    (folder / "state.txt").write_text("T= 0\n  X= 1 2 3\n")
    with pytest.raises(SceneError, match="1 points where the body has"):
        _scene(folder)
