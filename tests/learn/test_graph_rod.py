"""RodManipulator's configuration-space graph: collision detection on the observation, the
fingertip inverse of the re-contact expert, and the experts on the FEM scene."""

import numpy as np
import pytest

from pliant.errors import ModelError
from pliant.learn.graph.rod import BendTable, RodGeometry, finger_contacts, rod_graph

GEOMETRY = RodGeometry(
    fingers=np.array([[0.0, -25.0], [0.0, 25.0]]),
    finger_radius=6.0,
    rod_size=(10.0, 80.0, 10.0),
    length_scale=50.0,
)
ROD_CENTRE = np.array([0.0, 0.0, -10.0])


def observation(tips: np.ndarray, heading: float, centre=ROD_CENTRE) -> np.ndarray:
    """The environment's observation for fingertip centres `tips` (2, 3) and a rod turned by
    `heading` (rad): 3 points a fingertip (1 mm above its centre, +3 mm in x, in y)."""
    points = []
    for tip in tips:
        above = tip + [0.0, 0.0, 1.0]
        points += [above, above + [3.0, 0.0, 0.0], above + [0.0, 3.0, 0.0]]
    angles = [heading / (2 * np.pi), 1.0]
    return np.concatenate([np.ravel(points) / 50.0, np.asarray(centre) / 50.0, angles])


def turned(point_in_rod_frame, heading):
    """A point given across/along/up the rod, in the world."""
    across, along, up = point_in_rod_frame
    c, s = np.cos(heading), np.sin(heading)
    # across = (c, s), along = (-s, c): the rod's long axis starts along y.
    return ROD_CENTRE + [c * across - s * along, s * across + c * along, up]


@pytest.mark.parametrize("heading", [0.0, 0.7, 2.0, -1.2])
def test_collision_detection_in_the_rods_frame(heading):
    graph = rod_graph(GEOMETRY)
    top = [turned([1.0, -20.0, 5.0], heading), turned([-2.0, 22.0, 5.5], heading)]
    assert finger_contacts(GEOMETRY, observation(np.array(top), heading)) == ["top", "top"]
    assert graph.node_of(observation(np.array(top), heading)) == 1
    # Beside: below the top face, the fingertip's disc (radius 6) touching a side face.
    side = [turned([11.5, -20.0, 0.0], heading), turned([-10.5, 20.0, -2.0], heading)]
    assert finger_contacts(GEOMETRY, observation(np.array(side), heading)) == ["side", "side"]
    assert graph.node_of(observation(np.array(side), heading)) == 2
    # Lifted over the top, or low but clear of the sides, or beyond the rod's ends: free.
    free = [turned([0.0, -20.0, 12.0], heading), turned([25.0, 0.0, 0.0], heading)]
    assert graph.node_of(observation(np.array(free), heading)) == 0
    assert finger_contacts(GEOMETRY, observation(np.array([top[0], free[1]]), heading)) == [
        "top",
        "free",
    ]
    beyond = [turned([0.0, -46.5, 5.0], heading), turned([0.0, 49.0, 0.0], heading)]
    assert finger_contacts(GEOMETRY, observation(np.array(beyond), heading)) == ["free", "free"]
    # Low at an end face, or diagonally off a corner within the margin: beside.
    ends = [turned([0.0, -47.5, 0.0], heading), turned([9.0, 44.0, 0.0], heading)]
    assert finger_contacts(GEOMETRY, observation(np.array(ends), heading)) == ["side", "side"]
    # One finger beside wins over the other on top: the pinch's configuration.
    assert graph.node_of(observation(np.array([top[0], side[1]]), heading)) == 2


def test_observations_of_another_shape_or_not_finite_are_refused():
    good = observation(np.zeros((2, 3)), 0.0)
    with pytest.raises(ValueError, match="23 finite values"):
        finger_contacts(GEOMETRY, good[:-1])
    bad = good.copy()
    bad[19] = np.nan
    with pytest.raises(ValueError, match="non-finite"):
        rod_graph(GEOMETRY).node_of(bad)


def test_rod_pose_from_the_observation():
    obs = observation(np.zeros((2, 3)), 5.0, centre=[1.0, -2.0, -10.0])
    centre, heading = GEOMETRY.rod(obs)
    np.testing.assert_allclose(centre, [1.0, -2.0, -10.0])
    assert heading == pytest.approx(5.0)
    np.testing.assert_allclose(GEOMETRY.tips(obs), 0.0, atol=1e-12)


def test_bend_table_inverse():
    table = BendTable(
        np.array([0.0, 5.0, 10.0]), np.array([0.0, 10.0, 16.0]), np.array([0.0, 2.0, 8.0])
    )
    # 13 mm of reach: half way between 10 and 16, a pull of 7.5 mm, split along (3, -4) / 5.
    pulls = table.cables(np.array([7.8, -10.4]))
    np.testing.assert_allclose(pulls, [7.5 * 0.6, 0.0, 0.0, 7.5 * 0.8])
    np.testing.assert_allclose(table.cables(np.array([-5.0, 0.0])), [0.0, 0.0, 2.5, 0.0])
    np.testing.assert_allclose(table.cables(np.zeros(2)), 0.0)


def test_stroke_places_the_fingertips_over_the_rods_axis():
    """The stroke's first action bends each finger towards the point of the rod's axis nearest
    to it: for a rod turned by 30°, finger 0 (at y = -25) towards (25 sin cos, 25 sin²)."""
    from pliant.learn.graph.rod import stroke_expert

    class Env:  # what the expert reads of the environment
        class unwrapped:  # noqa: N801
            max_commands = np.full(8, 15.0)
            base_low, base_high = -20.0, 5.0

    table = BendTable(np.array([0.0, 15.0]), np.array([0.0, 30.0]), np.array([0.0, 10.0]))
    expert = stroke_expert(GEOMETRY, table, Env)
    theta = np.radians(30.0)
    action = expert.act(observation(np.zeros((2, 3)), theta), 0)
    pulls = 0.5 * (action[:8] + 1.0) * 15.0
    expected = 25 * np.sin(theta) * np.array([np.cos(theta), np.sin(theta)])  # finger 0
    np.testing.assert_allclose(pulls[:4], [*(expected / 2.0), 0.0, 0.0], atol=1e-5)
    np.testing.assert_allclose(pulls[4:], [0.0, 0.0, *(expected / 2.0)], atol=1e-5)
    assert action[8] == pytest.approx(1.0)  # the base raised
    assert len(expert) == 6 and expert.start_nodes == (0, 1, 2)


def test_pinch_needs_the_base_to_go_low_enough():
    from pliant.learn.graph.rod import pinch_expert

    class Env:
        class unwrapped:  # noqa: N801
            max_commands = np.full(8, 15.0)
            base_low, base_high = -10.0, 5.0

    with pytest.raises(ModelError, match="base_low"):
        pinch_expert(Env)


def test_experts_reconfigure_the_contacts_past_280_degrees():
    """On the FEM scene (mesh 6 mm): the on-top stroke alone stalls below 90° (there the
    fingertips cannot land on the rod's top), the experts chained by the rod's angle carry it
    through 90° by the pinch and on past 280° within 50 steps."""
    from pliant.learn.graph.rod import angle_rule, expert_rollout
    from pliant.learn.graph.scenes import make_scene

    scene = make_scene("RodManipulator", goal_low=4 * np.pi, goal_high=4 * np.pi, mesh_size=6.0)
    geometry = RodGeometry.of(scene.env)  # read from the model: fingers_mesh's defaults
    np.testing.assert_allclose(geometry.fingers, [[0.0, -25.0], [0.0, 25.0]], atol=1e-9)
    assert geometry.finger_radius == pytest.approx(6.0)
    assert geometry.rod_size == pytest.approx((10.0, 80.0, 10.0)) and geometry.margin == 2.0
    assert [e.name for e in scene.experts] == ["stroke", "pinch"]
    alone = expert_rollout(scene, lambda obs: "stroke", 40)
    assert 20.0 < alone["max_angle_deg"] < 90.0
    chained = expert_rollout(scene, angle_rule(45.0), 50)
    assert chained["max_angle_deg"] > 280.0
    assert {1, 2} <= set(chained["nodes"])  # on top, then beside: a reconfiguration


def test_cli_trains_the_rod_graph_with_its_experts(tmp_path):
    """``pliant graph train RodManipulator``: the graph with its two experts trains and
    evaluates from the CLI (the evaluation reports the rod's final angle); the scene has no
    convex internal agents, and says so."""
    import json

    from typer.testing import CliRunner

    from pliant.cli import app

    config = tmp_path / "config.json"
    settings = {"hidden": 32, "d": 8, "batch_size": 16, "learning_starts": 20}
    config.write_text(json.dumps({"agent": settings, "env": {"mesh_size": 8.0}}))
    out = tmp_path / "rod"
    args = ["graph", "train", "RodManipulator", "--config", str(config), "--out", str(out)]
    result = CliRunner().invoke(
        app, [*args, "--steps", "40", "--eval-every", "40", "--eval-episodes", "1"]
    )
    assert result.exit_code == 0, result.output
    (last,) = json.loads((out / "history.json").read_text())["evaluations"]
    assert last["steps"] >= 40 and np.isfinite(last["final_angle"])
    refused = CliRunner().invoke(app, [*args, "--method", "convex", "--steps", "10"])
    assert refused.exit_code != 0 and "no convex internal agents" in refused.output
    refused = CliRunner().invoke(app, [*args, "--method", "convex_node", "--steps", "10"])
    assert refused.exit_code != 0 and "no convex_node internal agents" in refused.output
    with pytest.raises(ModelError, match="expert_penalty"):
        from pliant.learn.graph.scenes import make_scene

        make_scene("RodManipulator", expert_penalty="high", mesh_size=8.0)
