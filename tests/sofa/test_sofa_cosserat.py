"""Cosserat rods of SOFA's Cosserat plugin in Pliant (pliant.sofa.rods): SofaGym's
``createCosserat`` read into a RodBody.

tests/sofa/sofa_scenes/cosserat_cantilever.py (written for these tests in SofaGym's form) is
compared with the same rod built with Pliant's API (to round-off) and with beam theory's
small-deflection cantilever: tip deflection F L^3 / (3 E I) under an end load, q L^4 / (8 E I)
under its weight, tip slope F L^2 / (2 E I) (one-point quadrature on 10 elements: 0.2 %).
"""

from __future__ import annotations

import re
import textwrap
from pathlib import Path

import numpy as np
import pytest

from pliant.fem.loads import NodalForces
from pliant.fem.material import Material
from pliant.fem.rod import RodBody, RodSection
from pliant.model import Model
from pliant.sofa import SceneError, load_scene
from pliant.sofa.prefabs.sofagym import express_point
from pliant.solvers import ImplicitEuler, StaticSolver

SCENE = Path(__file__).parent / "sofa_scenes" / "cosserat_cantilever.py"
LENGTH, RADIUS, YOUNG, POISSON = 100.0, 1.0, 2.0e5, 0.45  # the scene's, SOFA's default nu
INERTIA = np.pi * RADIUS**4 / 4.0
N = 10  # elements (nbFramesF)


def _api_rod(**kwargs) -> RodBody:
    """The scene's rod by Pliant's API: 10 elements along x, d1 = y, clamped at the origin."""
    points = np.column_stack([np.linspace(0.0, LENGTH, N + 1), np.zeros(N + 1), np.zeros(N + 1)])
    return RodBody(
        points,
        RodSection.circle(RADIUS),
        Material(YOUNG, POISSON),
        normal=(0.0, 1.0, 0.0),
        clamped=[0],
        **kwargs,
    )


def test_end_load_matches_the_api_rod_and_the_cantilever_formula() -> None:
    """A massless rod with a ConstantForceField on its tip frame: solved statically (SOFA's
    implicit step without mass), as the API rod; the frames, strains and base written back."""
    force = -0.05
    scene = load_scene(SCENE, config={"tip_force": [0.0, 0.0, force, 0.0, 0.0, 0.0]})
    assert scene.solver_kind == "static" and scene.model.body.n_centreline == N + 1
    state = scene.solver().step(scene.model.rest_state())

    api = Model(_api_rod(total_mass=1.0, loads=[NodalForces([N], [0.0, 0.0, force])]))
    expected = StaticSolver(api).step(api.rest_state())
    np.testing.assert_allclose(state.positions, expected.positions, rtol=0, atol=1e-12)

    tip = state.positions[N]
    closed = force * LENGTH**3 / (3.0 * YOUNG * INERTIA)
    assert tip[2] == pytest.approx(closed, rel=5e-3)
    frames = scene.root.Rod.rigidBase.MappedFrames.FramesMO.position.value
    assert frames.shape == (N + 2, 7)  # SofaGym's frames: the base twice, then the tip
    np.testing.assert_allclose(frames[-1, :3], tip, atol=1e-12)
    # The strains (bending about y per length, one per section) add up to the tip slope.
    strains = scene.root.Rod.rateAngularDeform.rateAngularDeformMO.position.value
    slope = strains[:, 1].sum() * LENGTH / N
    assert slope == pytest.approx(-force * LENGTH**2 / (2.0 * YOUNG * INERTIA), rel=1e-4)
    assert np.abs(strains[:, [0, 2]]).max() < 1e-12


@pytest.mark.parametrize(("sections", "share"), [(1, 1.0 / 4.0), (2, 10.0 / 32.0)])
def test_sections_bend_as_sofas_piecewise_constant_strain(sections, share) -> None:
    """Fewer sections than frames: the elements of a section keep one curvature, as SOFA's
    strain is one per section. Under an end load F, one section of constant curvature
    deflects F L^3 / (4 E I) (energy E I k^2 L / 2 - F k L^2 / 2 least), two halves 10/32 of
    F L^3 / (E I) (curvatures 3 F L / (4 E I) and F L / (4 E I)), against the elastica's 1/3;
    the scene's rod is the API rod with those sections to round-off."""
    force = -0.05
    scene = load_scene(
        SCENE, config={"sections": sections, "tip_force": [0.0, 0.0, force, 0.0, 0.0, 0.0]}
    )
    state = scene.solver().step(scene.model.rest_state())
    label = np.repeat(np.arange(sections), N // sections)
    api = Model(
        _api_rod(total_mass=1.0, loads=[NodalForces([N], [0.0, 0.0, force])], sections=label)
    )
    expected = StaticSolver(api).step(api.rest_state())
    np.testing.assert_allclose(state.positions, expected.positions, rtol=0, atol=1e-12)
    closed = share * force * LENGTH**3 / (YOUNG * INERTIA)
    assert state.positions[N, 2] == pytest.approx(closed, rel=5e-3)
    turns = np.linalg.norm(np.diff(state.positions[N + 1 :], axis=0), axis=1)
    for part in np.split(turns, sections):  # one curvature a section
        assert np.ptp(part) < 1e-4 * part.max()


def test_weight_and_damping_match_the_api_rod_and_the_cantilever_formula() -> None:
    """A UniformMass on the frames under gravity: the scene's implicit steps (createCosserat's
    Rayleigh damping 0.1 and 0.2) are the API rod's; its static sag is q L^4 / (8 E I)."""
    mass, g = 1e-4, 9810.0
    scene = load_scene(SCENE, config={"mass": mass})
    assert scene.solver_kind == "dynamic"
    api = Model(
        _api_rod(total_mass=mass, gravity=(0.0, 0.0, -g), rayleigh_mass=0.1, rayleigh_stiffness=0.2)
    )
    ours, theirs = scene.solver(), ImplicitEuler(api, scene.dt, tangent="fresh")
    state, expected = scene.model.rest_state(), api.rest_state()
    for _ in range(3):
        state, expected = ours.step(state), theirs.step(expected)
    np.testing.assert_allclose(state.positions, expected.positions, rtol=0, atol=1e-12)
    assert state.positions[N, 2] < -1e-4  # it falls

    sag = StaticSolver(scene.model).step(scene.model.rest_state()).positions[N, 2]
    closed = -(mass * g / LENGTH) * LENGTH**4 / (8.0 * YOUNG * INERTIA)
    # Lumped masses on 10 elements: the end nodes carry half a share (1.2 % less sag).
    assert sag == pytest.approx(closed, rel=2e-2)


def test_rest_strain_written_by_a_script_curves_the_rod() -> None:
    """Writing the strains' rest_position (as SofaGym's CartStem controller does) sets the rest
    curvature: with no load the rod takes the arc, its tip turned by kappa L about y."""
    scene = load_scene(SCENE, config={"tip_force": [0.0] * 6})
    strains = scene.root.Rod.rateAngularDeform.rateAngularDeformMO
    kappa = 0.002
    with strains.rest_position.writeable() as rest:
        rest[:, 1] = kappa
    solver = scene.solver()
    state = solver.step(scene.model.rest_state())
    tip = state.positions[N]
    radius = 1.0 / kappa  # the arc of curvature kappa from the origin along x, bent to -z
    angle = kappa * LENGTH
    np.testing.assert_allclose(
        tip, [radius * np.sin(angle), 0.0, -radius * (1.0 - np.cos(angle))], atol=2e-3
    )
    assert strains.position.value[:, 1] == pytest.approx(kappa, rel=1e-6)


def test_rod_on_a_sliding_cart_carrying_a_welded_ball(tmp_path) -> None:
    """SofaGym's CartStem in small: the rod's base is a cart (a rigid body with a mass, a
    PartialFixedConstraint leaving x free, a ConstantForceField), a ball welded on its tip by a
    BilateralInteractionConstraint. The ball's and the cart's masses sit on the rod's end
    nodes, the cart's held directions on the base's DoFs: the pair's centre of mass accelerates
    as F / (m_cart + m_ball) (the rod's own mass negligible) and the data read back follow."""
    scene_file = tmp_path / "cart_rod.py"
    scene_file.write_text(
        textwrap.dedent(
            """
            from sofagym.utils import createCosserat

            def createScene(rootNode, config):
                rootNode.gravity = [0.0, 0.0, 0.0]
                rootNode.dt = 0.01
                cart = rootNode.addChild("Cart")
                cart.addObject("MechanicalObject", template="Rigid3", name="RigidBaseMO",
                               position=[0, 0, 0, 0, -0.7071068, 0, 0.7071068])
                cart.addObject("UniformMass", totalMass=2.0)
                cart.addObject("PartialFixedConstraint", fixedDirections=[0, 1, 1, 1, 1, 1])
                cart.addObject("ConstantForceField", totalForce=[3.0, 0, 0, 0, 0, 0])
                shape = {"init_pos": [0, 0, 0], "tot_length": 20, "nbSectionS": 4,
                         "nbFramesF": 4}
                createCosserat(rootNode, shape, name="Stem", rigidBase=cart, youngModulus=1e6)
                ball = rootNode.addChild("ball")
                ball.addObject("MechanicalObject", template="Rigid3", translation=[0, 0, 20])
                ball.addObject("UniformMass", totalMass=1.0)
                rootNode.addObject("BilateralInteractionConstraint", template="Rigid3",
                                   object1="@/ball/MechanicalObject",
                                   object2="@/Stem/Cart/MappedFrames/FramesMO",
                                   first_point=0, second_point=5)
            """
        )
    )
    scene = load_scene(scene_file, config={})
    body = scene.model.body
    assert body.n_centreline == 5
    np.testing.assert_allclose(body.rest_positions[4], [0.0, 0.0, 20.0], atol=1e-6)  # upright
    assert body.node_masses[0] > 2.0 and body.node_masses[4] > 1.0
    solver, state = scene.solver(), scene.model.rest_state()
    for _ in range(20):
        state = solver.step(state)
    cart = scene.root.Stem.Cart.RigidBaseMO.position.value[0]
    np.testing.assert_allclose(cart[1:3], 0.0, atol=1e-12)
    np.testing.assert_allclose(cart[3:], [0.0, -0.7071068, 0.0, 0.7071068], atol=1e-6)
    ball = scene.root.ball.MechanicalObject.position.value[0]
    np.testing.assert_allclose(ball[:3], state.positions[4], atol=1e-12)
    assert 0.0 < ball[0] < cart[0]  # the ball lags behind the cart
    # Their centre of mass moves as a = F / (m_cart + m_ball) does under implicit Euler, a dt^2
    # n (n + 1) / 2 after n steps (less 1 %: createCosserat's Rayleigh mass damping, 0.1 / s).
    centre = (2.0 * cart[0] + 1.0 * ball[0]) / 3.0
    assert centre == pytest.approx(3.0 / 3.0 * scene.dt**2 * 20 * 21 / 2, rel=0.02)
    # A Rigid3 state's velocity and a ConstantForceField's force on it: six values each; a
    # force a script sets (as SofaGym's CartStem toolbox does) drives the next steps.
    assert scene.root.Stem.Cart.RigidBaseMO.velocity.value.shape == (1, 6)
    push = scene.root.Stem.Cart.ConstantForceField
    force = push.force.value.tolist()
    assert force == [0.0] * 6
    force[0] = -30.0
    push.force.value = np.array(force)
    for _ in range(5):
        state = solver.step(state)
    assert scene.root.Stem.Cart.RigidBaseMO.velocity.value[0, 0] < 0.0


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (
            "rod.rateAngularDeform.BeamHookeLawForceField.length = [5.0, 4.0]",
            "length: the sections' lengths",
        ),
        (
            'ball = rootNode.addChild("ball")\n'
            'ball.addObject("MechanicalObject", template="Rigid3", position=[0, 5, 0, 0, 0, 0, 1])'
            "\n"
            'ball.addObject("UniformMass", totalMass=1)',
            "moving rigid bodies beside a Cosserat rod are not supported (root/ball)",
        ),
    ],
)
def test_rod_scene_errors_name_what_is_wrong(tmp_path, extra, message) -> None:
    scene_file = tmp_path / "bad_rod.py"
    scene_file.write_text(
        textwrap.dedent(
            """
            from sofagym.utils import createCosserat

            def createScene(rootNode, config):
                rod = createCosserat(rootNode, {"init_pos": [0, 0, 0], "tot_length": 10,
                                     "nbSectionS": 2, "nbFramesF": 4}, name="Rod")
                rod.rigidBase.MappedFrames.addObject("UniformMass", totalMass=1)
            """
        )
        + textwrap.indent(extra, "    ")
        + "\n"
    )
    with pytest.raises(SceneError, match=re.escape(message)):
        load_scene(scene_file, config={})


def test_a_rod_that_never_moves_is_left_out(tmp_path) -> None:
    """SofaGym's drawn path: a rod with no mass, solid, load or contact stays where it is in
    SOFA; Pliant reads the scene without it (here nothing is left: no deformable body)."""
    scene_file = tmp_path / "drawn_rod.py"
    scene_file.write_text(
        textwrap.dedent(
            """
            from sofagym.utils import createCosserat

            def createScene(rootNode, config):
                shape = {"init_pos": [-5, 0, 0], "tot_length": 10, "nbSectionS": 1,
                         "nbFramesF": 1}
                createCosserat(rootNode, shape, name="Path")
            """
        )
    )
    with pytest.raises(SceneError, match="has no deformable body"):
        load_scene(scene_file, config={})


def test_express_point_is_a_pose_relative_to_a_base() -> None:
    """sofagym.utils.express_point: the positions' difference (world axes) and the rotation
    from the base's orientation to the point's."""
    turn = [0.0, 0.0, np.sin(np.pi / 4), np.cos(np.pi / 4)]  # 90 degrees about z
    half = [0.0, 0.0, np.sin(np.pi / 8), np.cos(np.pi / 8)]  # 45 degrees about z
    pose = express_point([1.0, 2.0, 3.0, *half], [2.0, 2.0, 5.0, *turn])
    np.testing.assert_allclose(pose, [1.0, 0.0, 2.0, *half], atol=1e-12)


def test_rod_frames_collide_with_a_static_obstacle(tmp_path) -> None:
    """addEdgeCollision's points on the frames, SofaGym's contact header: the cantilever,
    sagging under its weight (2.3 free at the tip), rests on a floor under its outer half at
    the header's contactDistance above it."""
    scene_file = tmp_path / "rod_floor.py"
    scene_file.write_text(
        textwrap.dedent(
            """
            from sofagym.header import addHeader
            from sofagym.utils import createCosserat

            def createScene(rootNode, config):
                addHeader(rootNode, alarmDistance=0.5, contactDistance=0.1,
                          gravity=[0, 0, -9810.0], dt=0.01, mu="0")
                shape = {"init_pos": [0, 0, 0], "tot_length": 100, "nbSectionS": 10,
                         "nbFramesF": 10}
                rod = createCosserat(rootNode, shape, name="Rod", radius=1.0, youngModulus=2e5,
                                     buildCollision=True)
                rod.rigidBase.addObject("FixedConstraint", indices=0)
                rod.rigidBase.MappedFrames.addObject("UniformMass", totalMass=3e-4)
                floor = rootNode.addChild("floor")
                corners = [[50, -10, -1], [150, -10, -1], [150, 10, -1], [50, 10, -1]]
                floor.addObject("MeshTopology", name="mesh", position=corners,
                                triangles=[0, 1, 2, 0, 2, 3])
                floor.addObject("MechanicalObject", position="@mesh.position")
                floor.addObject("TriangleCollisionModel", moving=0, simulated=0)
            """
        )
    )
    scene = load_scene(scene_file, config={})
    assert scene.model.contacts is not None
    heights = StaticSolver(scene.model).step(scene.model.rest_state()).positions[: N + 1, 2]
    assert heights[N] == pytest.approx(-0.9, abs=1e-6)
    assert np.all(heights >= -0.9 - 1e-6) and np.all(np.diff(heights) < 0)
