"""The FEM Trunk's pushes of the cube, recorded and replayed on its proxy
(:mod:`pliant.transfer.pushes`), and the proxy's cube keywords they are fitted with."""

from __future__ import annotations

import numpy as np
import pytest

from pliant.errors import ModelError
from pliant.proxy import trunk_proxy
from pliant.transfer.pushes import Pushes, cube_travel, fem_pushes, proxy_pushes

FEM = {"substeps": 30, "max_long_displacement": 14.0, "max_short_displacement": 8.0}


def hold(cables: np.ndarray, base: float = 0.0):
    """A policy that asks for the same absolute cables (actions in [-1, 1]) every step."""
    action = np.r_[cables, base]
    return lambda obs, rng: action


def test_fem_pushes_record_the_cables_the_fem_reached() -> None:
    slack = fem_pushes(hold(-np.ones(8)), 1, steps=2, env_kwargs=FEM)
    assert slack.actions.shape == (1, 2, 9) and slack.cubes.shape == (1, 3, 3)
    # nothing pulled: each cable shortened only as much as the trunk's sag shortens its path
    assert np.all(slack.actions[0, :, :8] < -0.5)
    assert cube_travel(slack.cubes)[0] < 0.1

    # the long +x cable (index 3) to 10 mm of its 14: 1 mm a sub-step, reached in one step,
    # and it is what the replay records
    cables = -np.ones(8)
    cables[3] = 2.0 * 10.0 / 14.0 - 1.0
    pull = fem_pushes(hold(cables), 1, steps=1, env_kwargs=FEM)
    assert pull.actions[0, 0, 3] == pytest.approx(cables[3], abs=3e-3)  # 0.02 mm


def test_fem_pushes_refuse_courses_that_the_proxy_cannot_replay() -> None:
    with pytest.raises(ModelError, match="fraction"):
        fem_pushes(hold(-np.ones(8)), 1, env_kwargs={**FEM, "max_short_displacement": 12.0})
    with pytest.raises(ModelError, match="one episode"):
        fem_pushes(hold(-np.ones(8)), 0, env_kwargs=FEM)
    with pytest.raises(ModelError, match="Box\\(9\\)"):
        fem_pushes(hold(-np.ones(4)), 1, env_kwargs={**FEM, "planar": True})


def test_replayed_on_the_proxy_a_strike_moves_the_cube_and_a_slippery_one_further() -> None:
    steps = 4
    actions = np.zeros((2, steps, 9))
    actions[:, :, :8] = -1.0
    actions[1, :, [3, 7]] = 1.0  # the second episode bends towards +x: towards the cube
    cubes = np.zeros((2, steps + 1, 3))
    pushes = Pushes(actions, cubes, np.array(["slack", "strike"]))
    free = proxy_pushes(pushes, {"bend_limit": 0.2})
    travel = cube_travel(free)
    assert travel[0] < 0.1 and travel[1] > 5.0
    assert free[1, -1, 0] > free[1, 0, 0]  # pushed along +x
    slippery = proxy_pushes(pushes, {"bend_limit": 0.2, "cube_friction": 0.05})
    assert cube_travel(slippery)[1] > 1.3 * travel[1]  # it slides on after the strike


def test_the_proxy_cube_keywords_reach_the_model() -> None:
    proxy = trunk_proxy(cube_friction=0.6, cube_damping=3.0, contact_radius=7.0)
    cube = proxy.model.rigid_bodies[0]
    assert (cube.friction, cube.linear_damping) == (0.6, 3.0)
    assert proxy.model.contacts.thickness == 7.0
    assert trunk_proxy().model.rigid_bodies[0].friction == 0.3  # the trunk's by default
    with pytest.raises(ModelError, match="cube_damping"):
        trunk_proxy(cube_damping=-1.0)


def test_pushes_check_their_shapes() -> None:
    with pytest.raises(ModelError, match="T \\+ 1"):
        Pushes(np.zeros((2, 3, 9)), np.zeros((2, 3, 3)), np.array(["a", "b"]))
