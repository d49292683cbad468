"""The Trunk proxy's axial commands: opposite cables pulled together shorten it without
bending it (``trunk_proxy(lower_cocontraction=, upper_cocontraction=)``,
``trunk_commands(axial=True)``)."""

from __future__ import annotations

import numpy as np
import pytest

from pliant.envs.trunk_push_proxy import TrunkPushProxyEnv
from pliant.proxy import trunk_proxy
from pliant.proxy.references import trunk_commands
from pliant.solvers import ImplicitEuler


def test_cables_pulled_together_are_an_axial_command_and_no_bending() -> None:
    together = trunk_commands(np.r_[[14.0] * 4, [8.0] * 4], axial=True)
    np.testing.assert_allclose(together, [0, 0, 0, 0, 0.2, 0.2, 0], atol=1e-12)
    one = np.zeros(8)
    one[3] = 14.0  # the long +x cable alone bends, and pulls nothing in common
    np.testing.assert_allclose(trunk_commands(one, axial=True)[4:6], 0.0)
    np.testing.assert_allclose(trunk_commands(one, axial=True)[:4], trunk_commands(one)[:4])
    assert len(trunk_commands(one)) == 5  # the proxy without axial commands is unchanged


def test_an_axial_command_shortens_each_beam_by_its_fraction() -> None:
    c_lower, c_upper = 0.1, 0.3
    proxy = trunk_proxy(
        lower_cocontraction=c_lower,
        upper_cocontraction=c_upper,
        gravity=(0.0, 0.0, 0.0),
        cube_position=None,
    )
    assert proxy.n_controls == 7 and proxy.actuation.names[4:] == ["lower_axial", "upper_axial"]
    solver, state = ImplicitEuler(proxy.model, 0.01), proxy.model.rest_state()
    proxy.apply([0, 0, 0, 0, 1, 1, 0])
    for _ in range(300):
        state = solver.step(state)
    x = proxy.skeleton(state.positions)
    element = np.linalg.norm(np.diff(x, axis=0), axis=1)
    rest = 195.0 / len(element)
    np.testing.assert_allclose(element[proxy.groups["lower"]], rest * (1 - c_lower), rtol=2e-3)
    np.testing.assert_allclose(element[proxy.groups["upper"]], rest * (1 - c_upper), rtol=2e-3)
    np.testing.assert_allclose(x[:, :2], 0.0, atol=1e-6)  # straight: no bending


def test_the_trunk_push_proxy_pulls_its_cables_together_into_a_shorter_trunk() -> None:
    with pytest.raises(ValueError, match="axial"):
        TrunkPushProxyEnv(lower_cocontraction=0.3, upper_cocontraction=0.3)
    env = TrunkPushProxyEnv(
        actions="cables", bend_limit=0.2, lower_cocontraction=0.3, upper_cocontraction=0.3
    )
    env.reset(seed=0)
    rest = env.proxy.skeleton(env.state.positions)[-1]
    env.step(np.r_[np.ones(8), 0.0])  # every cable to its course (14 / 8 mm), base still
    tip = env.proxy.skeleton(env.state.positions)[-1]
    assert rest[2] - tip[2] > 5.0  # 0.2 of 0.3 of 195 mm: about 12 mm
    assert abs(tip[0] - rest[0]) < 1.0  # and no sideways bend
