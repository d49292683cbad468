"""SofaGym's environment scenes in Pliant: ``createScene(rootNode, config)`` called with the
environment's configuration, SofaGym's shared helpers (``sofagym.header``), the scene's own
toolbox module beside it, its reward, goal and action controllers on the root, and SofaGym's
environment loop around it (:class:`pliant.envs.sofagym.SofaGymEnv`).

tests/sofa/sofa_scenes/gym_finger/ (written for these tests in SofaGym's form) is checked against
the same finger built with Pliant's API under the same cable commands: they agree to
round-off, and the toolbox's reward and goal read and move the scene as the API's states do.
"""

from __future__ import annotations

import shutil
import textwrap
from pathlib import Path

import gymnasium as gym
import meshio
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from pliant.constraints.base import EmbeddedPoints
from pliant.constraints.cable import CableActuator
from pliant.envs.base import ActionError
from pliant.envs.sofagym import SofaGymEnv
from pliant.fem.body import TetBody, nodes_in_box
from pliant.fem.material import Corotational
from pliant.mesh import box_beam
from pliant.model import Model
from pliant.sofa import SceneError, load_scene
from pliant.solvers import ImplicitEuler

SCENE = Path(__file__).parent / "sofa_scenes" / "gym_finger" / "GymFingerScene.py"
# The environment's configuration, as a SofaGym environment passes it to its scene.
CONFIG = {
    "scene": "GymFinger",
    "dt": 0.01,
    "goalPos": [55.0, 14.0, 5.0],
    "youngModulus": 400.0,  # not the scene's default (500): the configuration is used
    "action": 0,  # pull 5 mm over one environment step
    "scale_factor": 5,
    "source": [30.0, 0.0, 200.0],
    "target": [30.0, 0.0, 0.0],
    "zFar": 500,
}
N_STEPS = 8


@pytest.fixture
def mesh_dir(tmp_path):
    beam = box_beam(60.0, 10.0, 10.0, 6, 2, 2)
    meshio.write(tmp_path / "beam.vtu", meshio.Mesh(beam.points, [("tetra", beam.tets)]))
    return tmp_path


def _finger_by_api(young: float):
    """The scene's finger with Pliant's API: SOFA's "large" corotational law, uniform mass,
    Rayleigh damping 0.1 / 0.1, the clamped face fixed, one cable along the top."""
    mesh = box_beam(60.0, 10.0, 10.0, 6, 2, 2)
    body = TetBody(
        mesh,
        Corotational(young, 0.3, "large", inversion="tolerate"),
        mass="uniform",
        total_mass=0.05,
        frame_nodes=mesh.tets[:, :3],
        fixed_nodes=nodes_in_box(mesh.points, np.array([[-1.0, -1.0, -1.0], [1.0, 11.0, 11.0]])),
        gravity=(0.0, -9810.0, 0.0),
        rayleigh_mass=0.1,
        rayleigh_stiffness=0.1,
    )
    points = np.array([[x, 8.0, 5.0] for x in (10.0, 20.0, 30.0, 40.0, 50.0, 60.0)])
    cable = CableActuator(
        EmbeddedPoints(mesh, points, tolerance=0.1 * body.extent, outside="keep"),
        mesh.points,
        pull_point=np.array([0.0, 8.0, 5.0]),
        change_reference="lagged",
    )
    tip = EmbeddedPoints(mesh, np.array([[60.0, 5.0, 5.0]]), tolerance=0.1 * body.extent)
    return Model(body, actuators=[cable]), cable, tip


def test_a_sofagym_scene_steps_as_the_api_model(mesh_dir) -> None:
    """The configuration reaches createScene (Young's modulus, goal, action); the toolbox's
    animation ramps the cable over scale_factor steps (factor 0, 0.2, ..., 1 at each step's
    begin: 0, 1, ..., 5 mm, then held); the API's finger under the same commands ends at the
    same positions to round-off, and the toolbox's reward is the API tip's."""
    scene = load_scene(SCENE, config=CONFIG, mesh_dirs=[mesh_dir])
    assert len(scene.model.actuators) == 1 and len(scene.model.effectors) == 1
    np.testing.assert_array_equal(scene.model.effectors[0].goals, [CONFIG["goalPos"]])
    reward = scene.root.Reward
    reward.update(CONFIG["goalPos"])  # as SofaGym's environments do once the scene is built
    solver = scene.solver()
    state, by_scene = scene.model.rest_state(), []
    for _ in range(N_STEPS):
        state = solver.step(state)
        by_scene.append(state)

    model, cable, tip = _finger_by_api(CONFIG["youngModulus"])
    commands = 5.0 * np.minimum(np.arange(N_STEPS) / CONFIG["scale_factor"], 1.0)
    np.testing.assert_allclose(scene.root.applyAction.commands, commands, rtol=0, atol=1e-12)
    api = ImplicitEuler(model, CONFIG["dt"], tangent="fresh")
    state, by_api = model.rest_state(), []
    for command in commands:
        cable.value = command
        state = api.step(state)
        by_api.append(state)
    motion = np.abs(by_api[-1].positions - model.body.rest_positions).max()
    assert motion > 1.0
    for a, b in zip(by_scene, by_api, strict=True):
        np.testing.assert_allclose(a.positions, b.positions, rtol=0, atol=1e-9 * motion)

    goal = np.array(CONFIG["goalPos"])
    before = np.linalg.norm(tip.positions(model.body.rest_positions)[0] - goal)
    after = np.linalg.norm(tip.positions(by_api[-1].positions)[0] - goal)
    value, distance = reward.getReward()
    assert distance == pytest.approx(after, abs=1e-9 * motion)
    assert value == pytest.approx((before - after) / before, abs=1e-9)
    assert value > 0.0  # the pulled finger bends up towards the goal


def test_the_goal_setter_moves_the_effector_goal(mesh_dir) -> None:
    """The toolbox's goal setter writes the goal node's position; the effector's goal links
    to it and follows from the next step; the configuration given is not changed."""
    config = dict(CONFIG)
    scene = load_scene(SCENE, config=config, mesh_dirs=[mesh_dir])
    assert config == CONFIG
    scene.root.GoalSetter.update([50.0, -8.0, 5.0])
    scene.solver().step(scene.model.rest_state())
    np.testing.assert_array_equal(scene.model.effectors[0].goals, [[50.0, -8.0, 5.0]])
    assert scene.root.Goal.GoalMO.position.value.tolist() == [[50.0, -8.0, 5.0]]


def test_without_a_configuration_the_scene_takes_its_default(mesh_dir) -> None:
    scene = load_scene(SCENE, mesh_dirs=[mesh_dir])
    np.testing.assert_array_equal(scene.model.effectors[0].goals, [[58.0, 12.0, 5.0]])
    assert scene.model.body.material.young_modulus == 500.0


def _scene(folder: Path, body: str) -> Path:
    path = folder / "scene.py"
    path.write_text(textwrap.dedent(body))
    return path


@pytest.mark.parametrize(
    ("body", "message"),
    [
        (
            """
            from sofagym.utils import createCosserat

            def createScene(rootNode, config):
                for name in ("A", "B"):
                    shape = {"init_pos": [0, 0, 0], "tot_length": 10, "nbSectionS": 1,
                             "nbFramesF": 2}
                    rod = createCosserat(rootNode, shape, name=name)
                    rod.rigidBase.MappedFrames.addObject("UniformMass", totalMass=1)
            """,
            "Pliant simulates one moving Cosserat rod (the model's body), got 2",
        ),
        (
            """
            from sofagym.envs.Trunk.TrunkToolbox import startCmd

            def createScene(rootNode, config):
                pass
            """,
            "scene.py, line 2 (in <module>): imports 'sofagym.envs', which Pliant does not provide",
        ),
        (
            """
            from splib3.numerics import RigidBody

            def createScene(rootNode, config):
                pass
            """,
            "imports RigidBody from 'splib3.numerics', which Pliant does not provide",
        ),
        (
            """
            def createScene(rootNode):
                pass
            """,
            "createScene(rootNode) takes no configuration, one was given",
        ),
    ],
)
def test_what_pliant_lacks_of_sofagym_is_one_scene_error(tmp_path, body, message) -> None:
    with pytest.raises(SceneError) as error:
        load_scene(_scene(tmp_path, body), config={"dt": 0.01})
    assert message in str(error.value)


def test_sofagym_env_runs_sofagyms_loop_on_pliants_simulation(mesh_dir) -> None:
    """SofaGymEnv's step is SofaGym's: the toolbox's startCmd ramps the cable by 5 mm over
    dt (scale_factor - 1) (factor 0, 1/4, ..., 1 at the begin of the 5 steps), then getState
    and getReward; the observation is the API finger's tip under those commands and the goal,
    and the episode is truncated after timer_limit steps."""
    config = {
        **CONFIG,
        "action": None,
        "goal": True,
        "goalList": [[55.0, 14.0, 5.0]],
        "timer_limit": 2,
        "dim_state": 6,
    }
    env = SofaGymEnv(SCENE, config, action_space=gym.spaces.Discrete(2), mesh_dirs=[mesh_dir])
    obs, info = env.reset(seed=0)
    assert info["goal"] == [55.0, 14.0, 5.0] and env.observation_space.contains(obs)
    np.testing.assert_allclose(obs, [60.0, 5.0, 5.0, 55.0, 14.0, 5.0])
    obs, reward, done, truncated, _ = env.step(0)
    assert not done and not truncated

    model, cable, tip = _finger_by_api(CONFIG["youngModulus"])
    api = ImplicitEuler(model, CONFIG["dt"], tangent="fresh")
    state = model.rest_state()
    for factor in (0.0, 0.25, 0.5, 0.75, 1.0):
        cable.value = 5.0 * factor
        state = api.step(state)
    np.testing.assert_allclose(obs[:3], tip.positions(state.positions)[0], rtol=0, atol=1e-4)
    goal = np.array(config["goalList"][0])
    before = np.linalg.norm(np.array([60.0, 5.0, 5.0]) - goal)
    after = np.linalg.norm(tip.positions(state.positions)[0] - goal)
    assert reward == pytest.approx((before - after) / before, abs=1e-9)
    assert env.step(1)[3]  # truncated: timer_limit reached
    with pytest.raises(ActionError):
        env.step(2)


def test_a_failing_toolbox_is_the_scenes_error(mesh_dir, tmp_path) -> None:
    """An exception in the toolbox's functions is a SceneError at the toolbox's line."""
    folder = tmp_path / "scene"
    shutil.copytree(SCENE.parent, folder)
    toolbox = folder / "GymFingerToolbox.py"
    toolbox.write_text(toolbox.read_text().replace("PULL[action]", "PULL[action].missing"))
    config = {**CONFIG, "action": None, "timer_limit": 2, "dim_state": 6}
    env = SofaGymEnv(
        folder / SCENE.name, config, action_space=gym.spaces.Discrete(2), mesh_dirs=[mesh_dir]
    )
    env.reset(seed=0)
    with pytest.raises(SceneError, match=r"GymFingerToolbox.startCmd failed at GymFingerToolbox"):
        env.step(0)


def test_sofagym_env_passes_gymnasiums_checks(mesh_dir) -> None:
    """Gymnasium's check_env: spaces, seeded resets (the goal drawn from goalList), steps.
    The states are SofaGym's, unbounded: the checker's warning about it is expected."""
    config = {
        **CONFIG,
        "action": None,
        "goal": True,
        "goalList": [[55.0, 14.0, 5.0], [50.0, -8.0, 5.0]],
        "timer_limit": 3,
        "dim_state": 6,
    }
    env = SofaGymEnv(SCENE, config, action_space=gym.spaces.Discrete(2), mesh_dirs=[mesh_dir])
    with pytest.warns(UserWarning, match="infinity"):
        check_env(env, skip_render_check=True)
