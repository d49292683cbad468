"""MPC whose prediction is the learned condensed model (pliant.trajopt.learned, §6.2.1).

Uses the small Finger model committed for `pliant trajopt finger-mpc-learned`
(experiments/results/trajopt/learned/finger.pt): its W and delta_free against the FEM's at an
equilibrium inside its training box, the prediction's derivatives against torch's autograd and
finite differences, one MPC step within the bounds, a short loop closed on the FEM.
"""

from __future__ import annotations

import copy
from pathlib import Path

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from pliant import robots  # noqa: E402
from pliant.condensed.contact import ContactRobot  # noqa: E402
from pliant.condensed.learned import LearnedCondensedModel  # noqa: E402
from pliant.trajopt.learned import LearnedCondensedDynamics, LearnedMPC  # noqa: E402
from pliant.trajopt.scenarios import finger_two_goals  # noqa: E402

MODEL = Path(__file__).parents[2] / "experiments/results/trajopt/learned/finger.pt"


@pytest.fixture(scope="module")
def learned():
    return LearnedCondensedModel.load(MODEL)


@pytest.fixture(scope="module")
def scenario():
    return finger_two_goals(horizon=20, settle=1.0)


def inside(learned, fraction):
    box = learned.input_box
    return box.low + fraction * (box.high - box.low)


def test_learned_blocks_match_the_fem_inside_the_training_box(learned):
    """W[:, a] and delta_free of the prediction = the FEM's at the equilibrium reached for
    the same actuator distances (consistent tangent, the data's), within the network's error."""
    model = robots.build(learned.plan.robot, **learned.plan.robot_kwargs)
    robot = ContactRobot.for_plan(model, learned.plan)
    dyn = LearnedCondensedDynamics(learned, dt=0.02)
    n_a, n_rows = dyn.n_controls, learned.layout.n_rows
    for fraction in (np.array([0.5, 0.5]), np.array([0.3, 0.7])):
        delta_a = inside(learned, fraction)
        exact = robot.problem(robot.solve(robot.rest(), delta_a))
        w, free = dyn.blocks(delta_a)
        assert w.shape == (n_rows, n_a) and free.shape == (n_rows,)
        w_exact = exact.compliance[:, :n_a]
        # measured: 8e-5 relative and 8e-4 mm (test loss 1.5e-5); tolerances ten times that
        assert np.linalg.norm(w - w_exact) <= 1e-3 * np.linalg.norm(w_exact)
        assert np.max(np.abs(free - exact.free_distance)) <= 5e-3


def test_network_jacobian_is_autograd(learned):
    dyn = LearnedCondensedDynamics(learned, dt=0.02)
    delta = np.array([inside(learned, np.array([0.2, 0.6])), inside(learned, np.full(2, 0.9))])
    y, dy = dyn.network(delta, jacobian=True)
    net = copy.deepcopy(learned.network).double()
    rest = torch.tensor(np.concatenate(learned.rest))
    for row in range(2):
        x = torch.tensor(delta[row])
        expected = torch.autograd.functional.jacobian(
            lambda d: net.predict(torch.cat([d, rest])[None])[0], x
        )
        assert np.allclose(y[row], net.predict(torch.cat([x, rest])[None])[0].detach(), atol=1e-9)
        assert np.allclose(dy[row].T, expected.numpy(), rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize("activation", ["silu", "tanh"])
def test_numpy_passes_of_a_smooth_network_are_torchs(learned, activation):
    """The model's weights in a network of a smooth activation: the NumPy forward passes (the
    controller's, float32; the DDP's with its Jacobian, float64) against torch and autograd."""
    from pliant.condensed.learned import numpy_forward
    from pliant.condensed.networks import StandardisedMLP
    from pliant.trajopt.learned import NetworkJacobian

    net = StandardisedMLP.from_config({**learned.network.config(), "activation": activation})
    net.load_state_dict(learned.network.state_dict())
    smooth = copy.copy(learned)
    smooth.network = net
    rest = np.concatenate(learned.rest)
    delta = np.array([inside(learned, np.array([0.2, 0.6])), inside(learned, np.full(2, 0.9))])
    y, dy = NetworkJacobian(smooth)(delta, jacobian=True)
    double = copy.deepcopy(net).double()
    forward = numpy_forward(net)
    for row in range(2):
        x = torch.tensor(delta[row])
        full = torch.cat([x, torch.tensor(rest)])[None]
        exact = double.predict(full)[0].detach().numpy()
        expected = torch.autograd.functional.jacobian(
            lambda d: double.predict(torch.cat([d, torch.tensor(rest)])[None])[0], x
        )
        assert np.allclose(y[row], exact, atol=1e-9)
        assert np.allclose(dy[row].T, expected.numpy(), rtol=1e-9, atol=1e-12)
        scale = net.output_scale.scale.numpy()
        assert np.abs((forward(np.concatenate([delta[row], rest])) - exact) / scale).max() < 1e-4
    # and the activation is what a saved model keeps
    assert net.config()["activation"] == activation


def test_prediction_derivatives_are_finite_differences(learned):
    dyn = LearnedCondensedDynamics(learned, dt=0.02)
    m = dyn.n_positions
    x = np.concatenate([np.zeros(2 * m), inside(learned, np.array([0.4, 0.5]))])
    u = np.array([150.0, 20.0])
    rollout = dyn.rollout(x, u[None])
    fx, fu = dyn.derivatives(rollout)
    eps = 1e-6
    for j in range(dyn.n_state):
        e = np.zeros(dyn.n_state)
        e[j] = eps
        fd = (dyn.next_state(x + e, u) - dyn.next_state(x - e, u)) / (2 * eps)
        assert np.allclose(fx[0, :, j], fd, rtol=1e-5, atol=1e-6)
    for j in range(dyn.n_controls):  # linear in u: a step of 1 mN, clear of round-off
        e = np.zeros(dyn.n_controls)
        e[j] = 1.0
        fd = (dyn.next_state(x, u + e) - dyn.next_state(x, u - e)) / 2.0
        assert np.allclose(fu[0, :, j], fd, rtol=1e-5, atol=1e-8)


def test_one_learned_mpc_step_stays_within_bounds(learned, scenario):
    mpc = LearnedMPC(
        scenario.dynamics, learned, scenario.cost, scenario.bounds, horizon=20, max_iterations=3
    )
    result = mpc.run(scenario.start, steps=1)
    assert result.us.shape == (1, 2)
    assert scenario.bounds.violation(result.us) == 0.0
    assert np.all(np.isfinite(result.xs))


def test_short_learned_loop_moves_the_tip_toward_the_goal(learned, scenario):
    """Ten control steps (0.2 s) closed on the FEM, toward the first goal (5.6 mm away; the
    tip ends 1.5 mm from it)."""
    mpc = LearnedMPC(
        scenario.dynamics, learned, scenario.cost, scenario.bounds, horizon=10, max_iterations=2
    )
    result = mpc.run(scenario.start, steps=10)
    goal = scenario.goals[0]
    before = np.linalg.norm(result.xs[0, :3] - goal)
    after = np.linalg.norm(result.xs[-1, :3] - goal)
    assert scenario.bounds.violation(result.us) == 0.0
    assert after < 0.5 * before


def test_cli_finger_mpc_learned_writes_its_report(tmp_path):
    import json

    from typer.testing import CliRunner

    from pliant.cli import app

    result = CliRunner().invoke(
        app,
        ["trajopt", "finger-mpc-learned", "--model", str(MODEL), "--steps", "4"]
        + ["--horizon", "5", "--out", str(tmp_path)],
    )
    assert result.exit_code == 0, result.output
    report = json.loads((tmp_path / "finger_mpc_learned.json").read_text())
    assert not report["learned_model"]["trained_now"]
    assert all(r["bound_violation"] == 0.0 for r in report["runs"].values())
    assert (tmp_path / "finger_mpc_learned.png").stat().st_size > 0
