"""BeamAdapter's deployed instruments in Pliant (pliant.sofa.instruments on
pliant.fem.instruments): tests/sofa/sofa_scenes/instrument_deploy.py (written for these tests
in the form of SofaGym's CatheterBeam) against closed forms, and SofaGym's CatheterBeam and
CTR scenes (skipped without the SofaGym repository beside the project, or at $SOFAGYM).
"""

from __future__ import annotations

import os
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

from pliant.envs.sofagym import SofaGymEnv
from pliant.fem.instruments import Instrument, RestShape, node_abscissas
from pliant.sofa import SceneError, load_scene

SCENE = Path(__file__).parent / "sofa_scenes" / "instrument_deploy.py"
SOFAGYM = Path(os.environ.get("SOFAGYM", Path(__file__).resolve().parents[3] / "corpus/SofaGym"))
AXIS = np.array([0.0, 0.0, 1.0])  # the scene's entry direction
YOUNG, RADIUS = 1.0e4, 1.0
INERTIA = np.pi * RADIUS**4 / 4.0
SPIRE = {
    "length": 100.0,
    "straightLength": 0.0,
    "spireDiameter": 20.0,
    "spireHeight": 0.0,
    "densityOfBeams": [40],
    "youngModulus": YOUNG,
    "youngModulusExtremity": YOUNG,
    "radius": RADIUS,
    "massDensity": 1.0e-6,
}


def _run(config: dict, steps: int, push: tuple[float, float] | None = None):
    """The scene after `steps` steps; `push`: xtip[0] raised by push[0] a step up to push[1]
    (as SofaGym's actions write it)."""
    scene = load_scene(SCENE, config=config)
    solver, state = scene.solver(), scene.model.rest_state()
    controller = scene.root.InstrumentCombined.controller
    for _ in range(steps):
        if push is not None:
            with controller.xtip.writeable() as tips:
                tips[0] = min(tips[0] + push[0], push[1])
        state = solver.step(state)
    assert np.all(np.isfinite(state.positions))
    return scene


def _deployed(scene) -> np.ndarray:
    node = scene.root.InstrumentCombined
    return node.DOFs.position.value[int(node.controller.indexFirstNode.value) :]


def test_abscissas_sample_each_part_back_from_its_end() -> None:
    """A straight instrument of 100 sampled by 20 beams (5 apart) with its tip at 12: nodes at
    the entry, then 5 apart back from the tip."""
    straight = Instrument(RestShape(100.0, straight_length=100.0, density=(20,)))
    np.testing.assert_allclose(node_abscissas([straight], [12.0], 0.01), [0.0, 2.0, 7.0, 12.0])
    spire = RestShape(100.0, straight_length=60.0, spire_diameter=20.0, spire_height=0.0)
    assert spire.key_points == (0.0, 60.0, 100.0) and spire.density == (3, 8)  # SOFA's defaults
    point, frame = spire.transform(60.0 + 10.0 * np.pi / 2)  # a quarter turn of radius 10
    np.testing.assert_allclose(point, [70.0, 0.0, -10.0], atol=1e-12)
    np.testing.assert_allclose(frame[:, 0], [0.0, 0.0, -1.0], atol=1e-12)


def test_a_straight_instrument_pushed_in_stays_on_the_entry_axis_with_its_tip_at_xtip() -> None:
    """Pushed 1 a step to 50, free: straight along the entry, its tip at xtip (the Rayleigh
    damping lets it settle); the nodes not deployed wait at startingPos."""
    scene = _run({}, 80, push=(1.0, 50.0))
    node = scene.root.InstrumentCombined
    positions = node.DOFs.position.value
    first = int(node.controller.indexFirstNode.value)
    assert node.controller.xtip.value[0] == 50.0
    assert first == 30 - 11  # 0, then 10 beams of 5
    np.testing.assert_allclose(
        positions[:first], [[0, 0, 0, 0, -0.7071068, 0, 0.7071068]] * first, atol=1e-7
    )
    deployed = positions[first:, :3]
    assert np.abs(deployed[:, :2]).max() < 1e-9
    assert deployed[-1] @ AXIS == pytest.approx(50.0, abs=1e-4)
    np.testing.assert_allclose(deployed[:, 2], np.linspace(0.0, 50.0, 11), atol=1e-4)


def test_the_controller_speed_pushes_the_controlled_instrument() -> None:
    """speed 100 a second: xtip grows 1 a step of 0.01 s (written back), the tip following."""
    scene = _run({"speed": 100.0}, 30)
    assert scene.root.InstrumentCombined.controller.xtip.value[0] == pytest.approx(31.0)
    assert 20.0 < _deployed(scene)[-1, :3] @ AXIS < 31.0


def test_a_deployed_cantilever_bends_as_a_beam_under_a_tip_load() -> None:
    """50 deployed, a force F across it on the tip: F L^3 / (3 E I) (the rod's shear and the
    entry springs: within 0.5 %); two instruments over the same length add their E I."""
    length, force = 50.0, 1.0e-3
    scene = _run({"xtip": [length], "tip_force": [force, 0, 0, 0, 0, 0]}, 100)
    tip = _deployed(scene)[-1]
    closed = force * length**3 / (3.0 * YOUNG * INERTIA)
    assert tip[0] == pytest.approx(closed, rel=5e-3)
    stiffer = dict(SPIRE, straightLength=100.0, youngModulus=3.0 * YOUNG, radius=RADIUS)
    both = {"instruments": [dict(SPIRE, straightLength=100.0), stiffer], "xtip": [length, length]}
    scene = _run(both | {"rotation": [0.0, 0.0], "tip_force": [force, 0, 0, 0, 0, 0]}, 100)
    assert _deployed(scene)[-1][0] == pytest.approx(closed / 4.0, rel=5e-3)


def test_a_spire_deployed_freely_takes_its_curvature_and_turns_with_rotation() -> None:
    """20 of a spire of diameter 20 deployed: an arc of radius 10 (its tip at r sin 2 along
    the entry, r (1 - cos 2) across); rotationInstrument pi/2 turns it a quarter about the
    entry axis."""
    tips = []
    for turn in (0.0, np.pi / 2):
        scene = _run({"instruments": [SPIRE], "xtip": [20.0], "rotation": [turn]}, 60)
        points = _deployed(scene)[:, :3]
        a, b, c = points[0], points[len(points) // 2], points[-1]
        radius = (
            np.linalg.norm(a - b)
            * np.linalg.norm(b - c)
            * np.linalg.norm(c - a)
            / (2.0 * np.linalg.norm(np.cross(b - a, c - a)))
        )
        assert radius == pytest.approx(10.0, rel=1e-6)
        assert points[-1] @ AXIS == pytest.approx(10.0 * np.sin(2.0), rel=1e-6)
        tips.append(points[-1] - (points[-1] @ AXIS) * AXIS)
    across = 10.0 * (1.0 - np.cos(2.0))
    assert np.linalg.norm(tips[0]) == pytest.approx(across, rel=1e-6)
    np.testing.assert_allclose(tips[1], np.cross(AXIS, tips[0]), atol=1e-6 * across)


def test_an_instrument_pushed_against_a_wall_slides_along_it() -> None:
    """Pushed to 60 against a wall tilted 45 degrees across the entry's axis at z = 30: the
    deployed nodes stay on the entry's side, the tip touching the wall at the contact
    distance (0.5), the instrument bent along it; the collision node holds the deployed
    nodes."""
    scene = _run({"wall": 30.0}, 100, push=(1.0, 60.0))
    points = _deployed(scene)[:, :3]
    distance = (points[:, 2] - points[:, 0] - 30.0) / np.sqrt(2.0)  # to the wall, < 0 before it
    assert distance.max() == pytest.approx(-0.5, abs=0.05)
    assert distance[-1] == distance.max()
    assert points[-1, 0] > 10.0  # deflected along the wall, not through it
    collision = scene.root.InstrumentCombined.Collis.CollisionDOFs.position.value
    np.testing.assert_allclose(collision, points)


def test_unread_components_on_the_instrument_are_one_scene_error(tmp_path) -> None:
    text = SCENE.read_text().replace(
        "    return root\n",
        '    instrument.addObject("UniformMass", totalMass=1.0)\n    return root\n',
    )
    scene = tmp_path / "instrument_with_mass.py"
    scene.write_text(text)
    with pytest.raises(SceneError, match="UniformMass"):
        load_scene(scene)


@pytest.mark.skipif(not SOFAGYM.is_dir(), reason=f"SofaGym is not at {SOFAGYM} (set $SOFAGYM)")
@pytest.mark.parametrize("name", ["CatheterBeam", "CTR"])
def test_sofagym_instrument_scenes_load_and_step(name: str) -> None:
    """SofaGym's scene with its default configuration: pushed and turned as its actions do
    (writing the controller's xtip and rotationInstrument), 5 steps, its reward read."""
    path = SOFAGYM / "sofagym" / "envs" / name / f"{name}Scene.py"
    config = {"goalPos": [0.0, 0.0, 0.0], "dt": 0.01, "source": [0, 0, 160], "target": [0, 0, 0]}
    config |= {
        "goal_node": 0,
        "zFar": 4000,
        "seed": 0,
        "scale": 30,
        "mesh": "mesh/nasal_cavity.obj",
    }
    config |= {"rotation": [140.0, 0.0, 0.0], "translation": [0.0, 0.0, 0.0]}
    scene = load_scene(path, config=config)
    solver, state = scene.solver(), scene.model.rest_state()
    node = scene.root.InstrumentCombined
    for _ in range(5):
        with node.m_ircontroller.xtip.writeable() as tips:
            tips[0] += 2.0
        with node.m_ircontroller.rotationInstrument.writeable() as turns:
            turns[0] += 0.1
        state = solver.step(state)
    assert np.all(np.isfinite(state.positions))
    assert node.m_ircontroller.xtip.value[0] == pytest.approx(11.0)
    tip = node.DOFs.position.value[-1][:3]
    assert 2.0 < np.linalg.norm(tip) < 11.0  # on its way out (Rayleigh damping)
    assert (
        len(node.Collis.CollisionDOFs.position.value)
        == 60 - node.m_ircontroller.indexFirstNode.value
    )
    # CatheterBeam's goal is a vertex of its phantom (the MechanicalObject's points, scaled
    # and turned as SOFA's init leaves them), CTR's a point
    goal = 0 if name == "CatheterBeam" else [0.0, 0.0, 10.0]
    scene.root.Reward.update(goal)
    if name == "CatheterBeam":
        phantom = scene.root.CollisionModel.DOFs1.position.value
        assert len(phantom) > 1000 and np.ptp(phantom[:, 2]) > 100.0
    reward = scene.root.Reward.getReward()
    assert np.all(np.isfinite(reward))


@pytest.mark.skipif(not SOFAGYM.is_dir(), reason=f"SofaGym is not at {SOFAGYM} (set $SOFAGYM)")
def test_catheter_beam_environment_pushes_and_turns_through_its_toolbox() -> None:
    """SofaGym's CatheterBeam loop (pliant.envs.SofaGymEnv): its actions' animations
    (splib3's AnimationManagerController) write xtip and rotationInstrument, its getState
    reads them back with the tip."""
    path = SOFAGYM / "sofagym" / "envs" / "CatheterBeam" / "CatheterBeamScene.py"
    config = {"source": [0, 0, 160], "target": [0, 0, 0], "scale_factor": 10, "dt": 0.01}
    config |= {"timer_limit": 80, "zFar": 4000, "seed": None, "goal": True}
    config |= {"goalList": [1226, 1663], "dim_state": 12}
    env = SofaGymEnv(path, config, action_space=gym.spaces.Discrete(12))
    env.reset(seed=0)
    for action in (0, 0, 1):  # push 10 twice (2 scale / 2, scale 10), then turn 1/3
        state, reward, *_ = env.step(action)
    assert state[0] == pytest.approx(21.0)  # xtip of the catheter, from 1
    assert state[3] == pytest.approx(1.0 / 3.0)  # its rotation
    assert 1.0 < state[8] < 21.0  # the tip on its way along z (the entry's axis)
    assert np.isfinite(reward)
