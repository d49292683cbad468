"""SoftRobots' UnilateralPlaneConstraint (self-contact planes), JointConstraint and STLIB's
Rigidify, loaded from scenes written for these tests and checked against the same model built
with Pliant's API and against closed forms."""

from __future__ import annotations

import meshio
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from pliant.constraints.attachment import Attachment
from pliant.constraints.base import EmbeddedPoints
from pliant.constraints.contact import Contacts, PointPlanes
from pliant.fem.rigid import RigidBody
from pliant.geometry.collision import Box, Plane
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
    states as the frictionless contact of the corner with the plane y = 0."""
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
    solver, other = ImplicitEuler(floor, scene.dt, tangent="fresh"), floor.rest_state()
    for _ in range(6):
        other = solver.step(other)
    assert np.abs(other.positions - state.positions).max() < 1e-9


# ---------------------------------------------------------------------------------------------
# STLIB's Rigidify

RIGIDIFY_SCENE = """
from stlib3.physics.deformable import ElasticMaterialObject
from stlib3.physics.mixedmaterial import Rigidify
from stlib3.scene import MainHeader


def createScene(root):
    MainHeader(root, gravity=[0.0, -9810.0, 0.0], dt=0.01)
    modelling = root.addChild("Modelling")
    beam = ElasticMaterialObject(
        volumeMeshFileName="body.vtu", name="Beam", totalMass=0.01, youngModulus=1000.0,
        poissonRatio=0.3,
    )
    modelling.addChild(beam)
    {body}
    simulation = root.addChild("Simulation")
    simulation.addObject("EulerImplicitSolver")
    simulation.addObject("SparseLDLSolver")
    simulation.addChild({top})
"""


@pytest.fixture(scope="module")
def rigid_beam(tmp_path_factory):
    """The 40 mm beam as a volume mesh, its clamped face's nodes (x = 0) and its tip's."""
    folder = tmp_path_factory.mktemp("rigidify")
    mesh = box_beam(40.0, 10.0, 10.0, 4, 1, 1)
    meshio.write(folder / "body.vtu", meshio.Mesh(mesh.points, [("tetra", mesh.tets)]))
    clamp = np.flatnonzero(mesh.points[:, 0] < 1e-9).tolist()
    tip = np.flatnonzero(mesh.points[:, 0] > 40 - 1e-9).tolist()
    return mesh, folder, clamp, tip


def _rigidify_scene(folder, name: str, body: str, top: str = "rigid"):
    (folder / f"{name}.py").write_text(RIGIDIFY_SCENE.format(body=body, top=top))
    return load_scene(folder / f"{name}.py")


def test_a_held_rigidify_frame_holds_its_nodes(rigid_beam) -> None:
    """A frame with a FixedConstraint (STLIB's own example) holds its group: the same states
    as the body with those nodes fixed."""
    mesh, folder, clamp, _ = rigid_beam
    rigid = _rigidify_scene(
        folder,
        "held",
        f'rigid = Rigidify(modelling, beam, groupIndices=[{clamp}], name="Mixed")\n'
        '    rigid.RigidParts.addObject("FixedConstraint", indices=[0])',
    )
    fixed = _rigidify_scene(
        folder, "fixed", f'beam.addObject("FixedConstraint", indices={clamp})', top="beam"
    )
    assert np.array_equal(rigid.model.body.fixed_nodes, clamp)
    a, b = rigid.simulate(3), fixed.simulate(3)
    assert np.abs(a.positions - b.positions).max() < 1e-12
    assert np.abs(a.positions[clamp] - mesh.points[clamp]).max() == 0.0


def test_a_free_rigidify_frame_moves_its_nodes_rigidly(rigid_beam) -> None:
    """A free frame (at the tip group's barycentre, turned by Euler angles): the tip face
    keeps its shape (its nodes' distances stay those at rest) while the beam
    sags, the frame's pose is written back to its MechanicalObject, and the same model built
    with Pliant's API (a rigid body of a millionth of the nodes' mass, its nodes attached)
    gives the same states to round-off."""
    mesh, folder, clamp, tip = rigid_beam
    scene = _rigidify_scene(
        folder,
        "free",
        f"rigid = Rigidify(modelling, beam, groupIndices=[{clamp}, {tip}],"
        ' frames=[[0, 0, 0], [0, 0, 30]], name="Mixed")\n'
        '    rigid.RigidParts.addObject("FixedConstraint", indices=[0])',
    )
    state = scene.simulate(4)
    sag = mesh.points[tip, 1] - state.positions[tip, 1]
    assert sag.min() > 0.01
    rest = np.linalg.norm(mesh.points[tip][:, None] - mesh.points[tip][None], axis=2)
    now = np.linalg.norm(state.positions[tip][:, None] - state.positions[tip][None], axis=2)
    # Rigid to the attachment's linearisation over a step (second order in the frame's turn
    # per step, ~1e-6 mm here); the face without Rigidify changes by 1.5e-3 mm.
    assert np.abs(now - rest).max() < 1e-5
    dofs = scene.root.getChild("Simulation").getChild("Mixed").getChild("RigidParts")
    pose = dofs.getObject("dofs").position.value
    assert pose.shape == (2, 7)
    assert np.allclose(pose[1, :3], state.rigid_positions[0])
    body = scene.model.body
    frame = RigidBody(
        Box(np.full(3, 1e-3 * body.extent), position=mesh.points[tip].mean(axis=0)),
        1e-6 * body.node_masses[tip].sum(),
        rotation=Rotation.from_euler("xyz", [0, 0, 30], degrees=True).as_matrix(),
    )
    by_api = Model(
        body,
        rigid_bodies=[frame],
        attachments=[Attachment(EmbeddedPoints.at_nodes(tip), frame)],
    )
    solver, other = ImplicitEuler(by_api, scene.dt, tangent="fresh"), by_api.rest_state()
    for _ in range(4):
        other = solver.step(other)
    assert np.abs(other.positions - state.positions).max() < 1e-12


@pytest.mark.parametrize(
    ("call", "message"),
    [
        ("groupIndices=[[0, 1]], frames=[[0, 0, 0], [0, 0, 0]]", r"Rigidify.*frames: 2 frames"),
        ("groupIndices=[[0, 1]], frames=[[0, 0, 0, 0, 0]]", r"Rigidify.*frames: a frame has"),
        ("groupIndices=[[0, 999]]", r"Rigidify.*groupIndices: node 999 outside"),
        ("groupIndices=[[0, 1], [1, 2]]", r"Rigidify.*groupIndices: a node belongs to two"),
    ],
)
def test_rigidify_data_are_checked(rigid_beam, call, message) -> None:
    _, folder, _, _ = rigid_beam
    with pytest.raises(SceneError, match=message):
        _rigidify_scene(folder, "bad", f'rigid = Rigidify(modelling, beam, {call}, name="M")')


# ---------------------------------------------------------------------------------------------
# JointConstraint


def test_a_joint_constraint_is_named_with_why_and_its_data_checked(plane_beam) -> None:
    """SoftRobots' JointConstraint drives an articulation's Vec1 degree of freedom: the one
    SceneError names it, why, and its misspelt data."""
    _, folder, _ = plane_beam
    joint = (
        '<Node name="Arm"><MechanicalObject template="Vec1" position="0"/>'
        '<JointConstraint template="Vec1" index="0" value="0.5" valueTyp="force"/></Node>'
    )
    (folder / "joint.scn").write_text(
        PLANE_SCENE.format(plane='indices="0 1 2 3"').replace(
            "</Node></Node>", "</Node>" + joint + "</Node>"
        )
    )
    with pytest.raises(SceneError) as error:
        load_scene(folder / "joint.scn")
    message = str(error.value)
    assert "JointConstraint (at root/Arm: an articulation's degree of freedom" in message
    assert "JointConstraint.valueTyp (at root/Arm): no such data" in message


def test_a_free_rigidify_frame_under_a_static_solver_is_named(rigid_beam) -> None:
    mesh, folder, clamp, tip = rigid_beam
    (folder / "static.py").write_text(
        RIGIDIFY_SCENE.replace('"EulerImplicitSolver"', '"StaticSolver"').format(
            body=f"rigid = Rigidify(modelling, beam, groupIndices=[{clamp}, {tip}], name='M')",
            top="rigid",
        )
    )
    with pytest.raises(SceneError, match=r"free frame RigidParts\[0\] .* EulerImplicitSolver"):
        load_scene(folder / "static.py")
