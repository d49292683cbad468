"""SoftRobots' servo motors (ArticulatedSystemPlugin) turning STLIB's Rigidify frames, and
the ROIs a script computes with ``init()``: scenes written for these tests, checked against the
same model built with Pliant's API (a kinematic servo carrying the nodes) and closed forms."""

from __future__ import annotations

import math

import meshio
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from pliant.fem.rigid import DrivenNodes, KinematicBody, servo
from pliant.geometry.collision import Box
from pliant.mesh import box_beam
from pliant.model import Model
from pliant.sofa import SceneError, load_scene
from pliant.solvers import ImplicitEuler

# A beam clamped at x = 0 (a BoxROI computed while the script runs), its tip face (a
# SphereROI) rigidified and carried by the wheel of a servo written as SoftRobots' S90 is:
# a held Rigid3 base, a Vec1 angle pulled to its rest_position (the command), a wheel frame
# from an ArticulatedSystemMapping about the x axis through the tip's centre.
SERVO_SCENE = """
import Sofa
from stlib3.physics.deformable import ElasticMaterialObject
from stlib3.physics.mixedmaterial import Rigidify
from stlib3.scene import MainHeader
from stlib3.components import addOrientedBoxRoi


class Turn(Sofa.Core.Controller):
    def __init__(self, *args, **kwargs):
        Sofa.Core.Controller.__init__(self, *args, **kwargs)
        self.servo = kwargs["servo"]
        self.steps = 0

    def onAnimateBeginEvent(self, event):
        self.steps += 1
        self.servo.angleIn = {rate} * self.steps


def Servo(name):
    motor = Sofa.Core.Node(name)
    motor.addData("angleIn", 0.0)
    base = motor.addChild("ServoBody")
    base.addObject("MechanicalObject", name="dofs", template="Rigid3",
                   position=[[0, 0, 0, 0, 0, 0, 1]], translation=[40, 5, 5],
                   rotation=[0, 0, {yaw}])
    base.addObject("FixedProjectiveConstraint", indices=0)
    angle = motor.addChild("Articulation")
    angle.addObject("MechanicalObject", name="dofs", template="Vec1", position=[[0]],
                    rest_position=motor.angleIn.getLinkPath())
    angle.addObject("RestShapeSpringsForceField", points=0, stiffness=1e9)
    angle.addObject("UniformMass", totalMass=0.01)
    wheel = angle.addChild("ServoWheel")
    wheel.addObject("MechanicalObject", name="dofs", template="Rigid3",
                    position=[[0, 0, 0, 0, 0, 0, 1]] * 2)
    wheel.addObject("ArticulatedSystemMapping", input1="@../dofs",
                    input2="@../../ServoBody/dofs", output="@./")
    centre = angle.addChild("ArticulationCenter")
    centre.addObject("ArticulationCenter", parentIndex=0, childIndex=1,
                     posOnParent=[0, 0, 0], posOnChild=[0, 0, 0])
    joint = centre.addChild("Articulations")
    joint.addObject("Articulation", translation=False, rotation=True,
                    rotationAxis={axis}, articulationIndex=0)
    angle.addObject("ArticulatedHierarchyContainer")
    return motor


def createScene(root):
    MainHeader(root, gravity=[0.0, -9810.0, 0.0], dt=0.01)
    simulation = root.addChild("Simulation")
    simulation.addObject("EulerImplicitSolver")
    simulation.addObject("SparseLDLSolver")
    motor = simulation.addChild(Servo("Servo"))
    beam = ElasticMaterialObject(volumeMeshFileName="body.vtu", name="Beam", totalMass=0.01,
                                 youngModulus=1000.0, poissonRatio=0.3)
    modelling = root.addChild("Modelling")
    modelling.addChild(beam)
    beam.dofs.init()
    clamp = addOrientedBoxRoi(beam, position=[list(p) for p in beam.dofs.rest_position.value],
                              name="clamp", translation=[0, 5, 5], scale=[2, 12, 12])
    clamp.init()
    beam.addObject("FixedConstraint", indices=clamp.indices.value)
    tip = beam.addObject("SphereROI", name="tip", centers=[40, 5, 5], radii=[7.5])
    tip.init()
    rigid = Rigidify(modelling, beam, groupIndices=[list(tip.indices.value)],
                     frames=[[40, 5, 5, 0, 0, 0, 1]], name="Mixed")
    parts = rigid.RigidParts
    motor.Articulation.ServoWheel.addChild(parts)
    parts.addObject("SubsetMultiMapping", input=[motor.Articulation.ServoWheel.getLinkPath()],
                    output="@./", indexPairs=[0, 1])
    simulation.addChild(rigid)
    root.addObject(Turn(name="Turn", servo=motor))
"""
RATE = 0.05  # the angle commanded at step k: RATE k radians


@pytest.fixture(scope="module")
def servo_beam(tmp_path_factory):
    """The 40 mm beam's folder, mesh, clamped nodes (x = 0) and tip nodes (x = 40)."""
    folder = tmp_path_factory.mktemp("servo")
    mesh = box_beam(40.0, 10.0, 10.0, 4, 1, 1)
    meshio.write(folder / "body.vtu", meshio.Mesh(mesh.points, [("tetra", mesh.tets)]))
    clamp = np.flatnonzero(mesh.points[:, 0] < 1e-9)
    tip = np.flatnonzero(mesh.points[:, 0] > 40 - 1e-9)
    return folder, mesh, clamp, tip


def _load(folder, name: str, *, axis=(1, 0, 0), yaw=0.0):
    text = SERVO_SCENE.format(rate=RATE, axis=list(axis), yaw=yaw)
    (folder / f"{name}.py").write_text(text)
    return load_scene(folder / f"{name}.py")


def test_a_servo_turns_its_rigidified_nodes_as_the_api_does(servo_beam) -> None:
    """The ROIs computed in the script hold the clamp's and the tip's nodes; the servo's
    wheel turns the tip about the beam's axis by each step's command at the end of that step
    (closed form: the rest tip turned about (40, 5, 5), to round-off); the same body built
    with Pliant's API, its tip carried by a kinematic servo whose angle over a step is the
    command of that step, gives the same states."""
    folder, mesh, clamp, tip = servo_beam
    scene = _load(folder, "servo")
    body = scene.model.body
    assert set(tip) <= set(body.fixed_nodes) and set(clamp) <= set(body.fixed_nodes)
    assert len(body.fixed_nodes) == len(clamp) + len(tip)
    centre = np.array([40.0, 5.0, 5.0])
    carrier = KinematicBody(
        Box(np.full(3, 1e-3), position=centre),
        servo(centre, [1, 0, 0], lambda t: RATE * math.ceil(t / 0.01 - 1e-6), centre),
    )
    api = Model(body, drivers=[DrivenNodes(tip, carrier)])
    solver, reference = scene.solver(), ImplicitEuler(api, scene.dt, tangent="fresh")
    a, b = scene.model.rest_state(), api.rest_state()
    for _ in range(4):
        a, b = solver.step(a), reference.step(b)
        assert np.abs(a.positions - b.positions).max() < 1e-10
    turn = Rotation.from_rotvec([4 * RATE, 0.0, 0.0]).as_matrix()
    expected = centre + (mesh.points[tip] - centre) @ turn.T
    assert np.abs(a.positions[tip] - expected).max() < 1e-12
    assert np.abs(a.positions[clamp] - mesh.points[clamp]).max() == 0.0
    free = np.setdiff1d(np.arange(mesh.n_nodes), np.union1d(tip, clamp))
    assert np.abs(a.positions[free] - mesh.points[free]).max() > 0.1  # the beam twists
    # the angle and the wheel's frame written back where scripts read them
    motor = scene.root.Simulation.Servo
    assert motor.Articulation.dofs.position.value[0][0] == pytest.approx(4 * RATE)
    wheel = motor.Articulation.ServoWheel.dofs.position.value
    assert np.allclose(Rotation.from_quat(wheel[1, 3:]).as_rotvec(), [4 * RATE, 0, 0])


def test_the_servo_axis_is_in_its_base_frame(servo_beam) -> None:
    """A base turned 90 degrees about z turns the wheel's axis (1, 0, 0) to (0, 1, 0): the
    tip turns about y through its centre (closed form)."""
    folder, mesh, _, tip = servo_beam
    state = _load(folder, "yawed", yaw=90.0).simulate(2)
    centre = np.array([40.0, 5.0, 5.0])
    turn = Rotation.from_rotvec([0.0, 2 * RATE, 0.0]).as_matrix()
    expected = centre + (mesh.points[tip] - centre) @ turn.T
    assert np.abs(state.positions[tip] - expected).max() < 1e-12


def test_an_articulation_pliant_does_not_read_is_named(servo_beam) -> None:
    """A prismatic articulation is no servo: one SceneError names it."""
    folder, *_ = servo_beam
    text = SERVO_SCENE.format(rate=RATE, axis=[1, 0, 0], yaw=0.0).replace(
        "translation=False, rotation=True", "translation=True, rotation=False"
    )
    (folder / "slider.py").write_text(text)
    with pytest.raises(SceneError, match="Articulation: Pliant reads a rotation"):
        load_scene(folder / "slider.py")


def test_splib_handles_import_and_name_what_pliant_does_not_do(tmp_path) -> None:
    """SPLIB's RigidDof imports; moving a servo's base with it is named in the scene's
    error. SofaPrefab is a decorator and a base class."""
    (tmp_path / "handles.py").write_text(
        "from splib3.numerics import RigidDof\n"
        "from splib3.objectmodel import SofaPrefab\n\n"
        "class Box(SofaPrefab):\n"
        "    def __init__(self, node):\n"
        "        self.node = node.addChild('Box')\n\n"
        "def createScene(root):\n"
        "    Box(root)\n"
        "    dofs = root.Box.addObject('MechanicalObject', template='Rigid3')\n"
        "    RigidDof(dofs).setPosition([0, 0, 1])\n"
    )
    with pytest.raises(SceneError, match=r"handles.py, line 11.*RigidDof.setPosition"):
        load_scene(tmp_path / "handles.py")
