"""Scenes of rigid bodies alone (pliant.sofa.rigid_scene): BilateralInteractionConstraint,
SlidingConstraint, PartialFixedConstraint and ConstantForceField on Rigid3 frames, checked
against closed forms; what Pliant does not read is named in one SceneError."""

from __future__ import annotations

import textwrap

import numpy as np
import pytest

from pliant.constraints.rigid_joints import BallJoint, SlidingJoint
from pliant.sofa import SceneError, load_scene

G = 9.81
HEADER = """
def createScene(root):
    root.gravity = [0.0, -9.81, 0.0]
    root.dt = {dt}
    root.addObject("FreeMotionAnimationLoop")
    root.addObject("GenericConstraintSolver", tolerance=1e-9, maxIterations=100)
"""
BODY = """
    body = root.addChild("{name}")
    body.addObject("EulerImplicitSolver")
    body.addObject("CGLinearSolver", iterations=25, tolerance=1e-9, threshold=1e-9)
    body.addObject("MechanicalObject", template="Rigid3", position={pose})
    body.addObject("UniformMass", totalMass={mass})
    body.addObject("UncoupledConstraintCorrection")
    body.addObject("SphereCollisionModel", radius=0.1)
    point = body.addChild("Point")
    point.addObject("MechanicalObject", name="dofs", template="Vec3", position={local})
    point.addObject("RigidMapping")
"""


def _scene(tmp_path, text: str, name: str = "scene.py"):
    path = tmp_path / name
    path.write_text(textwrap.dedent(text))
    return path


def _pendulum(tmp_path, d: float, theta: float, dt: float, template: str = "Vec3"):
    start = [float(d * np.sin(theta)), float(-d * np.cos(theta)), 0.0]
    text = HEADER.format(dt=dt) + BODY.format(
        name="Ball", pose=[*start, 0, 0, 0, 1], mass=2.0, local=[[-start[0], -start[1], 0.0]]
    )
    text += f"""
    pivot = root.addChild("Pivot")
    pivot.addObject("MechanicalObject", name="dofs", template="Vec3", position=[[0, 0, 0]])
    root.addObject("BilateralInteractionConstraint", template="{template}",
                   object1="@Ball/Point/dofs", object2="@Pivot/dofs",
                   first_point=[0], second_point=[0])
"""
    return _scene(tmp_path, text)


def test_a_pendulum_on_a_bilateral_constraint_swings_at_its_period(tmp_path) -> None:
    """A Rigid3 ball (UniformMass totalMass m: SOFA's inertia m I, per unit mass the
    identity) whose mapped point is held on a still point: a compound pendulum of period
    2 pi sqrt(I_pivot / (m g d)), I_pivot = m (1 + d^2); its length held."""
    d, theta, dt = 0.5, 0.05, 0.01
    scene = load_scene(_pendulum(tmp_path, d, theta, dt))
    (joint,) = scene.model.joints
    assert isinstance(joint, BallJoint) and joint.body_b is None
    period = 2 * np.pi * np.sqrt((1.0 + d * d) / (G * d))
    solver, state = scene.solver(), scene.model.rest_state()
    x, lengths = [], []
    for _ in range(int(1.2 * period / dt)):
        state = solver.step(state)
        x.append(state.rigid_positions[0, 0])
        lengths.append(np.linalg.norm(state.rigid_positions[0]))
    x, t = np.array(x), dt * (1 + np.arange(len(x)))
    down = np.flatnonzero((x[:-1] > 0) & (x[1:] <= 0))[0]
    up = np.flatnonzero((x[:-1] < 0) & (x[1:] >= 0))[0]
    half = (t[up] + dt * x[up] / (x[up] - x[up + 1])) - (
        t[down] + dt * x[down] / (x[down] - x[down + 1])
    )
    assert 2 * half == pytest.approx(period, rel=5e-3)
    assert np.max(np.abs(np.array(lengths) - d)) < 1e-5 * d
    # the ball's MechanicalObject holds its pose, as scripts read it
    pose = scene.root.Ball.MechanicalObject.position.value[0]
    np.testing.assert_allclose(pose[:3], state.rigid_positions[0])


def test_a_cart_on_a_sliding_constraint_moves_along_its_line(tmp_path) -> None:
    """A cart whose point slides on an inclined line (two still points), its turns held by a
    PartialFixedConstraint, pushed along the line by a ConstantForceField that a script
    sets: speed along the line (g . a + F / m) t, nothing across it."""
    axis = np.array([1.0, -1.0, 0.0]) / np.sqrt(2.0)
    dt, mass, push = 0.01, 2.0, 3.0
    text = HEADER.format(dt=dt) + BODY.format(
        name="Cart", pose=[0, 0, 0, 0, 0, 0, 1], mass=mass, local=[[0.0, 0.0, 0.0]]
    )
    text += """
    body.addObject("PartialFixedConstraint", fixedDirections=[0, 0, 0, 1, 1, 1])
    body.addObject("ConstantForceField", name="Push", totalForce=[0, 0, 0, 0, 0, 0])
    line = root.addChild("Line")
    line.addObject("MechanicalObject", name="dofs", template="Vec3",
                   position=[[-1, 1, 0], [1, -1, 0]])
    root.addObject("SlidingConstraint", object1="@Cart/Point/dofs", object2="@Line/dofs",
                   sliding_point=0, axis_1=0, axis_2=1)
"""
    scene = load_scene(_scene(tmp_path, text))
    kinds = sorted(type(j).__name__ for j in scene.model.joints)
    assert kinds == [SlidingJoint.__name__]  # the turns: held by the body itself
    assert scene.model.rigid_bodies[0].held.tolist() == [False] * 3 + [True] * 3
    solver, state = scene.solver(), scene.model.rest_state()
    scene.root.Cart.Push.force = [*(push * axis), 0, 0, 0]  # as SofaGym's ApplyAction does
    n = 40
    for _ in range(n):
        state = solver.step(state)
    v, x = state.rigid_velocities[0], state.rigid_positions[0]
    along = G / np.sqrt(2.0) + push / mass
    assert v @ axis == pytest.approx(along * n * dt, rel=1e-9)
    assert np.linalg.norm(x - (x @ axis) * axis) < 1e-9
    assert np.abs(state.rigid_angular_velocities).max() < 1e-12


def test_what_a_rigid_scene_cannot_hold_is_named(tmp_path) -> None:
    rigid = _pendulum(tmp_path, 0.5, 0.1, 0.01, template="Rigid3")
    with pytest.raises(SceneError, match="Rigid3 BilateralInteractionConstraint"):
        load_scene(rigid)


def test_rest_shape_springs_on_a_rigid_body_oscillate_at_their_period(tmp_path) -> None:
    """A Rigid3 ball (m = 1) on a RestShapeSpringsForceField (stiffness 100) under gravity
    (y): it oscillates about y = -m g / k with period 2 pi sqrt(m / k)."""
    dt = 1e-3
    text = HEADER.format(dt=dt) + BODY.format(
        name="Ball", pose=[0, 0, 0, 0, 0, 0, 1], mass=1.0, local=[[0.0, 0.0, 0.0]]
    )
    text += '    body.addObject("RestShapeSpringsForceField", stiffness=100, angularStiffness=1)\n'
    scene = load_scene(_scene(tmp_path, text, "springs.py"))
    period = 2 * np.pi / 10.0
    solver, state = scene.solver(), scene.model.rest_state()
    y = []
    for _ in range(int(1.3 * period / dt)):
        state = solver.step(state)
        y.append(state.rigid_positions[0, 1] + G / 100.0)
    y, t = np.array(y), dt * (1 + np.arange(len(y)))
    down = np.flatnonzero((y[:-1] > 0) & (y[1:] <= 0))[0]
    up = np.flatnonzero((y[:-1] < 0) & (y[1:] >= 0))[0]
    at = [t[i] + dt * y[i] / (y[i] - y[i + 1]) for i in (down, up)]
    assert 2 * abs(at[1] - at[0]) == pytest.approx(period, rel=1e-3)


def test_pliant_run_renders_a_scene_of_rigid_bodies(tmp_path) -> None:
    """`pliant run` on a scene without deformable body: its frames, no VTU series."""
    from typer.testing import CliRunner

    from pliant.cli import app

    scene = _pendulum(tmp_path, 0.5, 0.1, 0.01)
    out = tmp_path / "out"
    result = CliRunner().invoke(
        app, ["run", str(scene), "--duration", "0.05", "--frames", "2", "--out", str(out)]
    )
    assert result.exit_code == 0, result.output
    assert (out / "scene" / "scene.gif").is_file()
    assert "1 rigid bodies" in result.output
