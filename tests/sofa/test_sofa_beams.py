"""BeamAdapter's beams in Pliant (pliant.sofa.beams): a Rigid3 beam with a BeamInterpolation
and an AdaptiveBeamForceFieldAndMass read into a RodBody, as SofaGym's StemPendulum builds it.

tests/sofa/sofa_scenes/beam_adapter_stem.py (written for these tests in the StemPendulum's
form) is checked against beam theory (a cantilever's tip deflection F L^3 / (3 E I) and slope
F L^2 / (2 E I), its sag under its weight q L^4 / (8 E I)), against the same rod built with
Pliant's API (to round-off), and as a hinged stem on an angular spring: a torque T turns it by
T / k at rest, and from rest it swings as theta(t) = T / k (1 - cos w t), w^2 = k / I.
"""

from __future__ import annotations

import dataclasses
import math
import re
import textwrap
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from pliant.fem.loads import NodalForces
from pliant.fem.material import Material
from pliant.fem.rod import RodBody, RodSection
from pliant.model import Model
from pliant.sofa import SceneError, load_scene
from pliant.sofa.beams import SHEAR_SHARE, BeamIndexWarning
from pliant.solvers import StaticSolver

SCENE = Path(__file__).parent / "sofa_scenes" / "beam_adapter_stem.py"
LENGTH, RADIUS, YOUNG, POISSON = 10.0, 0.2, 3.0e6, 0.4  # the scene's; SOFA's default nu
INERTIA = math.pi * RADIUS**4 / 4.0
AREA = math.pi * RADIUS**2
N = 10


def _tip_angle(scene) -> float:
    """The base frame's rotation about z, read back from the scene's MechanicalObject."""
    quat = scene.root.Beam.MechanicalObject.position.value[0, 3:]
    return float(Rotation.from_quat(quat).as_rotvec()[2])


def test_tip_load_matches_the_api_rod_and_the_cantilever_formula() -> None:
    """No mass (computeMass=False): solved statically, as SOFA's implicit step without mass;
    the frames and the point a frame carries written back."""
    force = 0.05
    scene = load_scene(
        SCENE, config={"density": None, "gravity": [0, 0, 0], "tip_force": [0, force, 0, 0, 0, 0]}
    )
    assert scene.solver_kind == "static" and scene.model.body.n_centreline == N + 1
    state = scene.solver().step(scene.model.rest_state())

    # Euler-Bernoulli: shear held to SHEAR_SHARE of the shortest element's bending compliance.
    material = Material(YOUNG, POISSON)
    shear = 12.0 * YOUNG * INERTIA / (material.mu * AREA * SHEAR_SHARE * (LENGTH / N) ** 2)
    section = dataclasses.replace(RodSection.circle(RADIUS), shear_coefficient=shear)
    points = np.column_stack([np.linspace(0.0, LENGTH, N + 1), np.zeros(N + 1), np.zeros(N + 1)])
    api = Model(
        RodBody(
            points,
            section,
            material,
            total_mass=1.0,
            normal=(0.0, 1.0, 0.0),
            clamped=[0],
            loads=[NodalForces([N], [0.0, force, 0.0])],
        )
    )
    expected = StaticSolver(api).step(api.rest_state())
    np.testing.assert_allclose(state.positions, expected.positions, rtol=0, atol=1e-12)

    tip = state.positions[N]
    assert tip[1] == pytest.approx(force * LENGTH**3 / (3.0 * YOUNG * INERTIA), rel=5e-3)
    assert abs(_tip_angle(scene)) < 1e-15  # the clamp
    frames = scene.root.Beam.MechanicalObject.position.value
    slope = Rotation.from_quat(frames[N, 3:]).as_rotvec()[2]
    assert slope == pytest.approx(force * LENGTH**2 / (2.0 * YOUNG * INERTIA), rel=5e-3)
    carried = scene.root.Beam.Tip.MechanicalObject.position.value[0]
    turned = Rotation.from_quat(frames[N, 3:]).apply([0.0, 0.5, 0.0])
    np.testing.assert_allclose(carried, tip + turned, atol=1e-12)


def test_weight_sags_as_a_cantilever_under_its_own_weight() -> None:
    """massDensity rho: a mass rho A per length, its weight q = rho A g; the static sag
    q L^4 / (8 E I) (lumped masses on 10 elements: the end nodes carry half a share)."""
    density, g = 1e-2, 981.0
    scene = load_scene(SCENE, config={"density": density})
    assert scene.solver_kind == "dynamic"
    body = scene.model.body
    assert body.node_masses[: N + 1].sum() == pytest.approx(density * AREA * LENGTH, rel=1e-12)
    sag = StaticSolver(scene.model).step(scene.model.rest_state()).positions[N, 1]
    assert sag == pytest.approx(-density * AREA * g * LENGTH**4 / (8 * YOUNG * INERTIA), rel=2e-2)
    state = scene.solver().step(scene.model.rest_state())
    assert state.positions[N, 1] < 0.0  # it falls


def test_a_controllers_torque_turns_the_hinge_by_torque_over_stiffness() -> None:
    """The StemPendulum's base: a PartialFixedConstraint leaving the rotation about z free,
    an angular RestShapeSpringsForceField k; a controller writes the moment into a Rigid3
    ConstantForceField's ``force`` (six values by default) before each step."""
    torque, k = 3.0, 300.0
    scene = load_scene(
        SCENE,
        config={
            "base": "hinge",
            "spring": k,
            "density": None,
            "gravity": [0, 0, 0],
            "base_torque": torque,
        },
    )
    assert scene.root.Beam.base.force.value.shape == (6,)
    state = scene.solver().step(scene.model.rest_state())
    assert _tip_angle(scene) == pytest.approx(torque / k, rel=1e-9)
    angle = torque / k  # the unloaded beam turns straight about its base
    np.testing.assert_allclose(
        state.positions[N], [LENGTH * math.cos(angle), LENGTH * math.sin(angle), 0.0], atol=1e-9
    )


def test_a_hinged_stem_swings_at_the_springs_frequency() -> None:
    """A stiff stem (E 3e9) hinged on the spring k with a 1 kg UniformMass at its tip (its
    rigid inertia, 1 about each axis, on the tip frame) and a negligible own mass: from rest
    under the torque T, theta(t) = T / k (1 - cos w t), w^2 = k / (m L^2 + 1); the first
    maximum at pi / w, within two steps (implicit Euler's period error is (w dt)^2 / 3)."""
    torque, k, mass, dt = 3.0, 300.0, 1.0, 0.01
    scene = load_scene(
        SCENE,
        config={
            "base": "hinge",
            "spring": k,
            "density": 1e-9,
            "tip_mass": mass,
            "gravity": [0, 0, 0],
            "base_torque": torque,
            "young": 3e9,
            "dt": dt,
        },
    )
    omega = math.sqrt(k / (mass * LENGTH**2 + mass))
    solver, state = scene.solver(), scene.model.rest_state()
    angles = []
    for _ in range(int(1.3 * math.pi / omega / dt)):
        state = solver.step(state)
        angles.append(_tip_angle(scene))
    first_max = (int(np.argmax(angles)) + 1) * dt
    assert first_max == pytest.approx(math.pi / omega, abs=2 * dt)
    # Implicit Euler's damping over half a period: (1 + (w dt)^2)^(-n/2), n = pi / (w dt).
    damped = (1.0 + (omega * dt) ** 2) ** (-math.pi / (omega * dt) / 2.0)
    peak = torque / k * (1.0 + damped)
    assert max(angles) == pytest.approx(peak, rel=1e-2)


def test_a_mass_on_a_frame_the_beam_lacks_is_left_out_with_a_warning() -> None:
    """The StemPendulum's UniformMass names frame nbSections + 1, one past its tip: SOFA does
    not check it; Pliant leaves it out, saying so."""
    with pytest.warns(BeamIndexWarning, match=re.escape("[11] name no frame")):
        scene = load_scene(SCENE, config={"tip_mass": 1.0, "mass_index": N + 1})
    masses = scene.model.body.node_masses[: N + 1]
    assert masses.sum() == pytest.approx(1e-2 * AREA * LENGTH, rel=1e-12)


def test_a_rotated_beam_rests_where_its_frames_are() -> None:
    """The MechanicalObject's rotation turns the frames and their positions; straight=False
    rests at them: with no load the beam does not move."""
    scene = load_scene(
        SCENE, config={"rotation": [0, 0, 30], "straight": False, "gravity": [0, 0, 0]}
    )
    rest = scene.model.rest_state()
    turn = math.radians(30)
    np.testing.assert_allclose(
        rest.positions[N], [LENGTH * math.cos(turn), LENGTH * math.sin(turn), 0.0], atol=1e-12
    )
    state = scene.solver().step(rest)
    np.testing.assert_allclose(state.positions, rest.positions, atol=1e-12)


@pytest.mark.parametrize(
    ("objects", "message"),
    [
        (
            'beam.addObject("BeamInterpolation", radius=[0.2, 0.3])\n'
            'beam.addObject("AdaptiveBeamForceFieldAndMass")',
            "radius: one value for every edge",
        ),
        ('beam.addObject("BeamInterpolation")', "one AdaptiveBeamForceFieldAndMass must use it"),
        (
            'beam.addObject("BeamInterpolation", crossSectionShape="elliptic")\n'
            'beam.addObject("AdaptiveBeamForceFieldAndMass")',
            "'circular' or 'rectangular'",
        ),
    ],
)
def test_beam_scene_errors_name_what_is_wrong(tmp_path, objects, message) -> None:
    scene_file = tmp_path / "bad_beam.py"
    scene_file.write_text(
        textwrap.dedent(
            """
            def createScene(rootNode):
                beam = rootNode.addChild("Beam")
                beam.addObject("EulerImplicitSolver")
                beam.addObject("EdgeSetTopologyContainer", edges=[[0, 1], [1, 2]])
                beam.addObject("MechanicalObject", template="Rigid3",
                               position=[[0, 0, 0, 0, 0, 0, 1], [1, 0, 0, 0, 0, 0, 1],
                                         [2, 0, 0, 0, 0, 0, 1]])
            """
        )
        + textwrap.indent(objects, "    ")
        + "\n"
    )
    with pytest.raises(SceneError, match=re.escape(message)):
        load_scene(scene_file)
