"""SoftRobots' UnilateralPlaneConstraint (self-contact planes), JointConstraint and STLIB's
Rigidify, loaded from scenes written for these tests and checked against the same model built
with Pliant's API and against closed forms."""

from __future__ import annotations

import meshio
import numpy as np
import pytest

from pliant.constraints.base import EmbeddedPoints
from pliant.constraints.contact import Contacts, PointPlanes
from pliant.geometry.collision import Plane
from pliant.mesh import box_beam
from pliant.model import Model
from pliant.sofa import SceneError, load_scene
from pliant.solvers import ImplicitEuler, StaticSolver

# ---------------------------------------------------------------------------------------------
# UnilateralPlaneConstraint

PLANE_SCENE = """<Node name="root" dt="0.01" gravity="0 -9810 0">
<Node name="Body">
  <StaticSolver/>
  <MeshVTKLoader name="loader" filename="body.vtu"/>
  <MeshTopology src="@loader"/>
  <MechanicalObject name="dofs"/>
  <UniformMass totalMass="0.01"/>
  <TetrahedronFEMForceField youngModulus="1000" poissonRatio="0.3" method="polar"/>
  <BoxROI name="clamp" box="-1 -1 -1 10.1 11 11"/>
  <FixedConstraint indices="@clamp.indices"/>
  <UnilateralPlaneConstraint name="stop" {plane}/>
</Node></Node>"""


@pytest.fixture(scope="module")
def plane_beam(tmp_path_factory):
    """A cantilever (clamped over its first 10 mm) whose tip sags under gravity, and the
    nodes of the tip's lower corner and of a horizontal plane y = 0 through clamped nodes."""
    folder = tmp_path_factory.mktemp("plane")
    mesh = box_beam(40.0, 10.0, 10.0, 4, 1, 1)
    meshio.write(folder / "body.vtu", meshio.Mesh(mesh.points, [("tetra", mesh.tets)]))

    def node(x, y, z):
        return int(np.flatnonzero(np.all(np.isclose(mesh.points, [x, y, z]), axis=1))[0])

    # (p_c - p_b) x (p_d - p_b) = (0, 0, 10) x (10, 0, 0) = (0, 100, 0): the normal is +y.
    nodes = [node(40, 0, 0), node(0, 0, 0), node(0, 0, 10), node(10, 0, 0)]
    return mesh, folder, nodes


def _plane_scene(folder, plane: str):
    (folder / "upc.scn").write_text(PLANE_SCENE.format(plane=plane))
    return load_scene(folder / "upc.scn")


def test_a_unilateral_plane_holds_its_point_on_the_normal_side(plane_beam) -> None:
    """The sagging tip corner meets the plane y = 0 of three clamped nodes and stays on it
    (closed form: y = 0 to the contact tolerance); the same model built with Pliant's API
    (PointPlanes) and as a frictionless contact of that node with the plane y = 0 (the plane's
    points are held) give the same state to round-off."""
    mesh, folder, nodes = plane_beam
    scene = _plane_scene(folder, f'indices="{" ".join(map(str, nodes))}"')
    state = scene.simulate(1)
    free = scene.model.body
    sag = StaticSolver(Model(free)).step(Model(free).rest_state())
    assert sag.positions[nodes[0], 1] < -0.05  # without the plane the corner goes through
    assert abs(state.positions[nodes[0], 1]) < 1e-5
    planes = PointPlanes(EmbeddedPoints.at_nodes(nodes))
    by_api = Model(free, contacts=Contacts([], planes=planes))
    api = StaticSolver(by_api).step(by_api.rest_state())
    assert np.abs(api.positions - state.positions).max() < 1e-12
    floor = Model(
        free,
        contacts=Contacts(
            [Plane(normal=[0, 1, 0], point=[0, 0, 0])], points=EmbeddedPoints.at_nodes(nodes[:1])
        ),
    )
    on_floor = StaticSolver(floor).step(floor.rest_state())
    assert np.abs(on_floor.positions - state.positions).max() < 1e-9


def test_a_flipped_unilateral_plane_lets_its_point_go(plane_beam) -> None:
    """flipNormal: the normal is -y, the corner is on its side all along: the beam sags as if
    the plane were not there."""
    mesh, folder, nodes = plane_beam
    scene = _plane_scene(folder, f'indices="{" ".join(map(str, nodes))}" flipNormal="1"')
    state = scene.simulate(1)
    free = Model(scene.model.body)
    sag = StaticSolver(free).step(free.rest_state())
    assert np.abs(sag.positions - state.positions).max() < 1e-9


@pytest.mark.parametrize(
    ("plane", "message"),
    [
        ('indices="0 1 2"', r"Body/stop\.indices: four point indices"),
        ('indices="0 1 2 999"', r"Body/stop\.indices: \[0, 1, 2, 999\] outside"),
        ('indices="0 1 2 3" flipNormals="1"', r"UnilateralPlaneConstraint\.flipNormals"),
        ('indices="0 1 2 3" endTime="0.5"', r"Body/stop\.endTime"),
    ],
)
def test_unilateral_plane_data_are_checked(plane_beam, plane, message) -> None:
    _, folder, _ = plane_beam
    with pytest.raises(SceneError, match=message):
        _plane_scene(folder, plane)


def test_a_unilateral_plane_of_aligned_points_is_refused(plane_beam) -> None:
    mesh, folder, _ = plane_beam
    aligned = [
        int(np.flatnonzero(np.all(np.isclose(mesh.points, p), axis=1))[0])
        for p in ([40, 0, 0], [0, 0, 0], [10, 0, 0], [20, 0, 0])
    ]
    with pytest.raises(SceneError, match="aligned"):
        _plane_scene(folder, f'indices="{" ".join(map(str, aligned))}"')


def test_a_unilateral_plane_in_a_dynamic_step_is_a_contact(plane_beam) -> None:
    """The implicit Euler step (the contacts' point columns) with the plane's rows: the same
    states as the frictionless contact of the corner with the plane y = 0, to the contact
    solver's tolerance (1e-5 mm; its sweeps start from other contact sets)."""
    mesh, folder, nodes = plane_beam
    text = PLANE_SCENE.replace("<StaticSolver/>", "<EulerImplicitSolver/>")
    (folder / "upc_dynamic.scn").write_text(
        text.format(plane=f'indices="{" ".join(map(str, nodes))}"')
    )
    scene = load_scene(folder / "upc_dynamic.scn")
    state = scene.simulate(6)
    assert state.positions[nodes[0], 1] > -1e-5
    floor = Model(
        scene.model.body,
        contacts=Contacts(
            [Plane(normal=[0, 1, 0], point=[0, 0, 0])],
            points=EmbeddedPoints.at_nodes(nodes[:1]),
            margin=100.0,
        ),
    )
    solver, other = ImplicitEuler(floor, scene.dt), floor.rest_state()
    for _ in range(6):
        other = solver.step(other)
    assert np.abs(other.positions - state.positions).max() < 1e-6
