"""SofaPython3 scene scripts as SoftRobots users write them: STLIB / SPLIB / SoftRobots
prefabs, Python controllers driving actuators each step, data read back, visual components.

Each scene of tests/sofa/sofa_scenes/ (written for these tests) is checked against the same model
built with Pliant's own API, stepped with the same commands: the two agree to round-off.
"""

from __future__ import annotations

import os
import shutil
import sys
import textwrap
from pathlib import Path

import meshio
import numpy as np
import pytest

from pliant.constraints.base import EmbeddedPoints
from pliant.constraints.cable import CableActuator
from pliant.constraints.cavity import CavityActuator, enclosed_volume
from pliant.fem.body import TetBody, nodes_in_box
from pliant.fem.loads import RestShapeSprings
from pliant.fem.material import Corotational
from pliant.mesh import box_beam
from pliant.model import Model
from pliant.sofa import SceneError, load_scene
from pliant.solvers import ImplicitEuler

SCENES = Path(__file__).parent / "sofa_scenes"


@pytest.fixture
def meshes(tmp_path):
    """The meshes the test scenes load: a 60 x 10 x 10 beam and a 10 mm block with its
    boundary as a cavity surface."""
    beam = box_beam(60.0, 10.0, 10.0, 6, 2, 2)
    meshio.write(tmp_path / "beam.vtu", meshio.Mesh(beam.points, [("tetra", beam.tets)]))
    block = box_beam(10.0, 10.0, 10.0, 2, 2, 2)
    meshio.write(tmp_path / "block.vtu", meshio.Mesh(block.points, [("tetra", block.tets)]))
    surface = block.boundary_triangles()
    meshio.write(tmp_path / "cavity.stl", meshio.Mesh(block.points, [("triangle", surface)]))
    return {"beam": beam, "block": block, "surface": surface, "folder": tmp_path}


def _step_all(solver, state, n_steps, before=None):
    states = []
    for k in range(n_steps):
        if before is not None:
            before(k)
        state = solver.step(state)
        states.append(state)
    return states


def test_meshes_are_found_where_sofa_finds_them(meshes, monkeypatch) -> None:
    """A mesh not beside the scene: found in SOFA_DATA_PATH's folders or $SOFA_ROOT/share (as
    SOFA finds its own meshes), the same scene as with mesh_dirs; else one SceneError."""
    monkeypatch.delenv("SOFA_DATA_PATH", raising=False)
    monkeypatch.delenv("SOFA_ROOT", raising=False)
    with pytest.raises(SceneError, match="beam.vtu.*SOFA_DATA_PATH"):
        load_scene(SCENES / "cable_beam.py")
    given = load_scene(SCENES / "cable_beam.py", mesh_dirs=[meshes["folder"]])
    monkeypatch.setenv("SOFA_DATA_PATH", f"/nonexistent{os.pathsep}{meshes['folder']}")
    found = load_scene(SCENES / "cable_beam.py")
    assert np.array_equal(found.model.body.mesh.points, given.model.body.mesh.points)
    monkeypatch.delenv("SOFA_DATA_PATH")
    share = meshes["folder"] / "sofa" / "share"
    share.mkdir(parents=True)
    (meshes["folder"] / "beam.vtu").rename(share / "beam.vtu")
    monkeypatch.setenv("SOFA_ROOT", str(meshes["folder"] / "sofa"))
    assert load_scene(SCENES / "cable_beam.py").model.body.n_elements == given.model.body.n_elements


def test_a_controller_drives_the_cable_as_the_api_does(meshes) -> None:
    """cable_beam.py's controller raises the cable's value by 0.2 each step: the same beam,
    springs and cable built with Pliant's API, the command set before each step, ends at
    the same positions to round-off; the data the controller reads back are the states'."""
    scene = load_scene(SCENES / "cable_beam.py", mesh_dirs=[meshes["folder"]])
    assert len(scene.model.actuators) == 1 and scene.solver_kind == "dynamic"
    solver = scene.solver()
    by_scene = _step_all(solver, scene.model.rest_state(), 5)

    mesh = meshes["beam"]
    held = nodes_in_box(mesh.points, np.array([[-1.0, -1.0, -1.0], [1.0, 11.0, 11.0]]))
    body = TetBody(
        mesh,
        Corotational(500.0, 0.3, "large", inversion="tolerate"),
        mass="uniform",
        total_mass=0.05,
        frame_nodes=mesh.tets[:, :3],
        loads=[RestShapeSprings(held, mesh.points, 1e12)],
        gravity=(0.0, -9810.0, 0.0),
    )
    points = np.array([[x, 8.0, 5.0] for x in (10.0, 20.0, 30.0, 40.0, 50.0, 60.0)])
    cable = CableActuator(
        EmbeddedPoints(mesh, points, tolerance=0.1 * body.extent, outside="keep"),
        mesh.points,
        pull_point=np.array([0.0, 8.0, 5.0]),
        change_reference="lagged",
    )
    model = Model(body, actuators=[cable])

    def pull(k):
        cable.value = 0.2 * (k + 1)

    by_api = _step_all(ImplicitEuler(model, 0.01, tangent="fresh"), model.rest_state(), 5, pull)
    motion = np.abs(by_api[-1].positions - mesh.points).max()
    assert motion > 0.5
    for a, b in zip(by_scene, by_api, strict=True):
        np.testing.assert_allclose(a.positions, b.positions, rtol=0, atol=1e-9 * motion)
    assert scene.root.Modelling is scene.root.Simulation.Modelling  # moved: two parents
    controller = scene.root.getObject("controller")
    tips = np.array([s.positions[-1] for s in by_scene])
    np.testing.assert_array_equal(np.array(controller.tips), tips)
    cable_data = scene.root.Simulation.Modelling.Beam.Cable.CableConstraint
    assert cable_data.displacement.value == pytest.approx(by_scene[-1].displacement[0])
    assert cable_data.value.value[0] == pytest.approx(1.0)


def test_an_animation_ramps_the_cavity_pressure_as_the_api_does(meshes) -> None:
    """cavity_block.py: splib3's animate ramps the pressure from 0 to 30 over 0.05 s
    (factor (t - t_first) / 0.05 at each step's begin, t_first = dt); the API's cavity with
    the same pressures, on the same block, ends at the same positions to round-off."""
    scene = load_scene(SCENES / "cavity_block.py", mesh_dirs=[meshes["folder"]])
    by_scene = scene.simulate(8)

    mesh = meshes["block"]
    body = TetBody(
        mesh,
        Corotational(1000.0, 0.3, "large", inversion="tolerate"),
        mass="uniform",
        total_mass=0.01,
        frame_nodes=mesh.tets[:, :3],
        fixed_nodes=np.flatnonzero(mesh.points[:, 0] <= 0.1),
        gravity=(0.0, 0.0, 0.0),
        rayleigh_mass=0.1,
        rayleigh_stiffness=0.1,
    )
    # The cavity's surface as the STL file holds it (single precision), carried by the body.
    stl = meshio.read(meshes["folder"] / "cavity.stl")
    walls = np.asarray(stl.points, dtype=float)
    surface = stl.cells_dict["triangle"]
    embedded = EmbeddedPoints(mesh, walls, tolerance=0.1 * body.extent, outside="keep")
    cavity = CavityActuator(
        surface,
        mesh.points,
        points=embedded,
        flip_normals=enclosed_volume(walls, surface) < 0.0,
        mode="force",
        min_force=-np.inf,
        change_reference="lagged",
    )
    model = Model(body, actuators=[cavity])

    def ramp(k):
        cavity.value = 30.0 * min(k * 0.01 / 0.05, 1.0)

    by_api = _step_all(ImplicitEuler(model, 0.01, tangent="fresh"), model.rest_state(), 8, ramp)[-1]
    motion = np.abs(by_api.positions - mesh.points).max()
    assert motion > 0.05
    np.testing.assert_allclose(by_scene.positions, by_api.positions, rtol=0, atol=1e-9 * motion)
    assert scene.model.actuators[0].value == 30.0


def test_the_sofa_modules_exist_only_while_a_scene_loads(meshes) -> None:
    before = {name for name in sys.modules if name.split(".")[0] in ("Sofa", "stlib3")}
    load_scene(SCENES / "cable_beam.py", mesh_dirs=[meshes["folder"]])
    after = {name for name in sys.modules if name.split(".")[0] in ("Sofa", "stlib3")}
    assert before == after == set()


def _scene(tmp_path: Path, body: str, extra: str = "") -> Path:
    """A script with a small beam (a Pliant mesh file beside it) and `body` inside
    createScene."""
    beam = box_beam(20.0, 5.0, 5.0, 2, 1, 1)
    meshio.write(tmp_path / "beam.vtu", meshio.Mesh(beam.points, [("tetra", beam.tets)]))
    script = tmp_path / "scene.py"
    script.write_text(
        textwrap.dedent(extra)
        + "\ndef createScene(rootNode):\n"
        + "    body = rootNode.addChild('Body')\n"
        + "    body.addObject('StaticSolver')\n"
        + "    body.addObject('MeshVTKLoader', name='loader', filename='beam.vtu')\n"
        + "    body.addObject('MechanicalObject', name='dofs')\n"
        + "    body.addObject('UniformMass', totalMass=0.01)\n"
        + textwrap.indent(textwrap.dedent(body), "    ")
    )
    return script


FEM = "body.addObject('TetrahedronFEMForceField', youngModulus=100, poissonRatio=0.3)\n"


@pytest.mark.parametrize(
    ("body", "extra", "message"),
    [
        (
            FEM + "body.addObject('BeamFEMForceField')\nbody.addObject('Foo')\n",
            "",
            r"BeamFEMForceField \(at root/Body\); Foo \(at root/Body\)",
        ),
        (
            "body.addObject('TetrahedronFEMForceField', youngModulos=100)\n",
            "",
            r"TetrahedronFEMForceField.youngModulos \(at root/Body\): no such data \(did you"
            r" mean 'youngModulus'\?\)",
        ),
        (FEM + "x = 1 / 0\n", "", r"scene.py, line 9 \(in createScene\): ZeroDivisionError"),
        (FEM + "raise SystemExit(2)\n", "", r"scene.py, line 9 \(in createScene\): SystemExit"),
        (
            FEM + "body.dofs.positon.value\n",
            "",
            r"line 9 .*root/Body/dofs: a MechanicalObject has no data field 'positon' \(did you"
            r" mean 'position'\?\)",
        ),
        (FEM + "rootNode.Bodyy\n", "", r"line 9 .*no child.*'Bodyy' \(did you mean 'Body'\?\)"),
        (
            FEM,
            "from softrobots.parts.finger import Finger\n",
            r"imports 'softrobots.parts', which Pliant does not provide",
        ),
    ],
    ids=["unknown", "misspelt", "python-error", "exit", "misspelt-read", "missing-child", "import"],
)
def test_what_a_scene_cannot_do_is_one_scene_error(tmp_path, body, extra, message) -> None:
    with pytest.raises(SceneError, match=message):
        load_scene(_scene(tmp_path, body, extra))


def test_a_controller_error_is_the_scenes_at_its_line(tmp_path) -> None:
    extra = """
    import Sofa.Core


    class Broken(Sofa.Core.Controller):
        def onAnimateBeginEvent(self, event):
            raise RuntimeError("no pressure sensor")
    """
    held = "body.addObject('FixedConstraint', indices=[0, 1, 2, 3])\n"
    script = _scene(tmp_path, FEM + held + "rootNode.addObject(Broken(name='broken'))\n", extra)
    scene = load_scene(script)
    with pytest.raises(SceneError, match=r"Broken.onAnimateBeginEvent failed at scene.py, line 7"):
        scene.simulate(1)


def test_pliant_run_reports_a_failing_create_scene_in_one_line(tmp_path) -> None:
    from typer.testing import CliRunner

    from pliant.cli import app

    script = _scene(tmp_path, FEM + "raise RuntimeError('mesh not ready')\n")
    result = CliRunner().invoke(app, ["run", str(script), "--out", str(tmp_path / "out")])
    assert result.exit_code != 0
    assert "scene.py, line 9 (in createScene): RuntimeError: mesh not ready" in result.output
    assert "a bug in Pliant" not in result.output


def test_box_corners_and_fem_variants_follow_sofa(tmp_path) -> None:
    """A BoxROI given max corner first holds the same nodes; SOFA's
    FastTetrahedralCorotationalForceField ("qr", the edge frame) bends the beam as
    TetrahedronFEMForceField's "large" does; a PointCollisionModel on the body's own
    MechanicalObject is accepted."""
    fixed = "body.addObject('BoxROI', name='box', box={})\n"
    fixed += "body.addObject('FixedConstraint', indices='@box.indices')\n"
    fixed += "body.addObject('BoxROI', name='tip', box=[19.9, -1, -1, 21, 6, 6])\n"
    fixed += "body.addObject('ConstantForceField', indices='@tip.indices', force=[0, -0.5, 0])\n"
    ends = []
    for fem, box in [
        (FEM, [-1, -1, -1, 0.1, 6, 6]),
        (FEM, [0.1, 6, 6, -1, -1, -1]),
        (FEM.replace("TetrahedronFEM", "FastTetrahedralCorotational"), [0.1, 6, 6, -1, -1, -1]),
    ]:
        ends.append(load_scene(_scene(tmp_path, fem + fixed.format(box))).simulate(1).positions)
    assert np.abs(ends[0] - box_beam(20.0, 5.0, 5.0, 2, 1, 1).points).max() > 0.01
    np.testing.assert_array_equal(ends[0], ends[1])
    np.testing.assert_array_equal(ends[0], ends[2])


def test_visual_only_scenes_still_need_a_body(tmp_path) -> None:
    script = tmp_path / "visual.py"
    script.write_text(
        "def createScene(root):\n"
        "    root.addObject('OglModel')\n"
        "    root.addObject('LightManager')\n"
        "    root.addObject('OglSceneFrame')\n"
    )
    with pytest.raises(SceneError, match="no deformable body"):
        load_scene(script)


def test_the_tutorial_scene_files_are_not_copied(tmp_path, meshes) -> None:
    """A scene runs from any folder: its meshes are found through mesh_dirs."""
    shutil.copy(SCENES / "cable_beam.py", tmp_path / "copy.py")
    assert load_scene(tmp_path / "copy.py").model.actuators


def test_floor_cube_and_a_moving_goal(meshes) -> None:
    """block_on_floor.py: STLIB's Floor is a plane at its translation (turned by its
    rotation), the Cube a rigid box of half size uniformScale, the block's own nodes its
    collision points; the controller's goal, moved 1 mm a step, is the effector's goal."""
    scene = load_scene(SCENES / "block_on_floor.py", mesh_dirs=[meshes["folder"]])
    contacts, (cube,) = scene.model.contacts, scene.model.rigid_bodies
    (floor,) = contacts.shapes
    assert type(floor).__name__ == "Plane"
    np.testing.assert_allclose(floor.normal, [0.0, 0.0, 1.0], atol=1e-12)
    assert floor.position[2] == pytest.approx(-2.0)
    assert len(contacts.points) == len(meshes["block"].points)
    assert contacts.friction == 0.3 and contacts.margin == 1.0
    np.testing.assert_allclose(cube.shape.half_extents, [3.0, 3.0, 3.0])
    state = scene.simulate(3)
    np.testing.assert_allclose(scene.model.effectors[0].goals, [[5.0, 5.0, 13.0]])
    assert state.positions[:, 2].min() > -2.0 - 0.1 - 1e-6  # above the floor, by thickness


def test_pliant_run_steps_a_scene_with_its_controller(meshes, tmp_path) -> None:
    """`pliant run` on cable_beam.py: the controller pulls 0.2 mm a step; after 3 steps the
    cable has shortened by 0.55 mm (the constraint holds on the step's linearisation)."""
    from typer.testing import CliRunner

    from pliant.cli import app

    scene = meshes["folder"] / "cable_beam.py"
    shutil.copy(SCENES / "cable_beam.py", scene)
    args = ["run", str(scene), "--duration", "0.03", "--frames", "1", "--out", str(tmp_path)]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 0, result.output
    assert "-> displacement [0.5" in result.output.replace("\n", " ")  # not 0: driven


def test_the_object_model_answers_as_sofapython3(tmp_path) -> None:
    """Node and component calls scenes make, recorded by the script into a Python attribute
    of its root; SofaGym's createScene(rootNode, config) gets an empty configuration."""
    body = FEM + textwrap.dedent(
        """
        body.addObject('FixedConstraint', name='held', indices=[0, 1, 2, 3])
        root = body.getRoot()
        rootNode.gravity.value = [0.0, 0.0, -9.81]
        rootNode.findData('dt').value = 0.02
        rootNode.checks = {
            "root": root is rootNode,
            "child": rootNode.getChild("Body") is body and rootNode.Body is body,
            "children": [c.name.value for c in rootNode.children],
            "objects": [o.getName() for o in body.objects][:3],
            "state": body.getMechanicalState().getLinkPath(),
            "link": body.held.indices.getLinkPath(),
            "indices": body.held.indices.value.tolist(),
            "missing": body.getObject("nothing"),
            "young": body.getObject("TetrahedronFEMForceField").youngModulus.value,
            "config": config,
        }
        """
    )
    script = _scene(tmp_path, body)
    script.write_text(
        script.read_text().replace("createScene(rootNode)", "createScene(rootNode, config)")
    )
    scene = load_scene(script)
    assert scene.root.checks == {
        "root": True,
        "child": True,
        "children": ["Body"],
        "objects": ["StaticSolver", "loader", "dofs"],
        "state": "@/Body/dofs",
        "link": "@/Body/held.indices",
        "indices": [0, 1, 2, 3],
        "missing": None,
        "young": 100.0,
        "config": {},
    }
    assert scene.dt == 0.02 and scene.model.body.gravity.tolist() == [0.0, 0.0, -9.81]


def test_a_prefab_refusal_names_the_scripts_line(tmp_path) -> None:
    extra = "from softrobots.actuators import PneumaticCavity\n"
    script = _scene(tmp_path, FEM + "PneumaticCavity(attachedTo=body)\n", extra)
    with pytest.raises(SceneError, match=r"scene.py, line 10 \(in createScene\): PneumaticCavity"):
        load_scene(script)


@pytest.mark.parametrize("value_type", ["pressure", "1"])
def test_a_cavity_pressure_acts_from_the_first_step(meshes, value_type) -> None:
    """PneumaticCavity(initialValue=20, valueType="pressure") inflates the block in the
    first step as the same scene at 0 does with its command set to 20 through the API
    ("1" is the option's index, as older scenes write it, and means volumeGrowth there)."""
    text = (SCENES / "cavity_block.py").read_text()
    text = text.replace('valueType="pressure",', f'valueType="{value_type}", initialValue=20.0,')
    text = text.replace("    animate(inflate", "    # animate(inflate")
    (meshes["folder"] / "initial.py").write_text(text)
    scene = load_scene(meshes["folder"] / "initial.py")
    first = scene.simulate(1).positions
    by_api = load_scene(SCENES / "cavity_block.py", mesh_dirs=[meshes["folder"]])
    by_api.model.actuators[0].value = 20.0
    if value_type == "1":
        assert scene.model.actuators[0].mode == "displacement"
        return
    expected = by_api.model.rest_state()
    expected = by_api.solver().solver.step(expected)  # without the scene's animation
    motion = np.abs(expected.positions - meshes["block"].points).max()
    assert motion > 0.01
    np.testing.assert_allclose(first, expected.positions, rtol=0, atol=1e-9 * motion)


def test_a_controller_moves_the_body_through_its_positions(tmp_path) -> None:
    """Positions a controller writes into the body's MechanicalObject are where the next
    step starts: a body shifted 1 mm along z, without load, stays there (a rigid motion)."""
    extra = """
    import Sofa.Core


    class Shift(Sofa.Core.Controller):
        def __init__(self, *args, **kwargs):
            Sofa.Core.Controller.__init__(self, *args, **kwargs)
            self.dofs = kwargs["dofs"]

        def onAnimateBeginEvent(self, event):
            if event["time"] == 0.0:
                with self.dofs.position.writeable() as x:
                    x[:, 2] += 1.0
    """
    body = FEM + "rootNode.gravity = [0, 0, 0]\nrootNode.addObject(Shift(dofs=body.dofs))\n"
    script = _scene(tmp_path, body, extra)
    script.write_text(script.read_text().replace("'StaticSolver'", "'EulerImplicitSolver'"))
    scene = load_scene(script)
    state = scene.simulate(2)
    rest = scene.model.body.rest_positions
    np.testing.assert_allclose(state.positions, rest + [0.0, 0.0, 1.0], rtol=0, atol=1e-9)


def test_a_first_order_euler_solver_steps_without_inertia(tmp_path) -> None:
    """EulerImplicitSolver with firstOrder (SoftRobots' T4 cable tutorials): the scene's solver
    is Pliant's first-order implicit Euler (tests/solvers/test_first_order.py checks its
    physics), not the second-order one with the flag ignored."""
    script = _scene(tmp_path, FEM + "body.addObject('FixedConstraint', indices=[0, 1, 2, 3])\n")
    text = script.read_text().replace(
        "body.addObject('StaticSolver')",
        "rootNode.gravity = [0, 0, -9810]\n"
        "    body.addObject('EulerImplicitSolver', firstOrder=True, rayleighMass=0.5)",
    )
    script.write_text(text)
    scene = load_scene(script)
    assert scene.solver_kind == "first-order"
    solver = scene.solver()
    assert isinstance(solver, ImplicitEuler) and solver.first_order
    model, dt = scene.model, scene.dt
    by_scene = scene.simulate(5)
    first, second = model.rest_state(), model.rest_state()
    for _ in range(5):
        first = ImplicitEuler(model, dt, tangent="fresh", first_order=True).step(first)
        second = ImplicitEuler(model, dt, tangent="fresh").step(second)
    sag = np.abs(first.positions - model.rest_state().positions).max()
    assert sag > 1e-3
    np.testing.assert_allclose(by_scene.positions, first.positions, rtol=0, atol=1e-12 * sag)
    assert np.abs(second.positions - first.positions).max() > 1e-2 * sag
