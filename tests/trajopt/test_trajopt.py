"""Trajectory optimisation with condensed FEM dynamics (pliant.trajopt, thesis §5.2).

Verified against known answers: the unconstrained DDP on a linear system is the LQR optimum
(Riccati recursion, written out here), the box-constrained one is crocoddyl's Box-FDDP
optimum, the condensed derivatives (Eq. 5.26-5.27) are finite differences of the FEM step.
"""

from __future__ import annotations

import numpy as np
import pytest

from pliant import robots
from pliant.errors import DivergenceError, InfeasibleProblemError, TrajectoryOptimisationError
from pliant.trajopt import (
    ActuationBounds,
    BoxDDP,
    CondensedDynamics,
    LinearDynamics,
    tracking_cost,
)
from pliant.trajopt.crocoddyl_backend import solve_frozen
from pliant.trajopt.ddp import backward_pass, compiled_backward_pass

H = 0.05  # time step of the mass-spring system


def mass_spring(n: int = 40):
    """A damped mass-spring (m = 1, k = 4, c = 0.2), semi-implicit in time, driven by a force,
    and a cost taking it to x = 1."""
    a = np.array([[1.0, H], [-4.0 * H, 1.0 - 0.2 * H]])
    b = np.array([[0.0], [H]])
    cost = tracking_cost(
        np.ones((n + 1, 1)),
        n_controls=1,
        velocity_weight=0.1,
        control_weight=0.01,
        terminal_weight=10.0,
    )
    return LinearDynamics(a, b), cost


def lqr(a, b, cost, x0):
    """The LQR optimum by the Riccati recursion with an affine term (tracking cost):
    P_k = Q_k + A^T P A - A^T P B (R + B^T P B)^-1 B^T P A, p_k likewise."""
    q, ref, r = cost.state_weights, cost.state_reference, np.diag(cost.control_weights)
    n = cost.horizon
    p_mat, p_vec = np.diag(q[n]), -q[n] * ref[n]
    gains = []
    for t in range(n - 1, -1, -1):
        quu, qux, qu = r + b.T @ p_mat @ b, b.T @ p_mat @ a, b.T @ p_vec
        big_k, small_k = -np.linalg.solve(quu, qux), -np.linalg.solve(quu, qu)
        gains.append((big_k, small_k))
        p_mat = np.diag(q[t]) + a.T @ p_mat @ a + qux.T @ big_k
        p_vec = -q[t] * ref[t] + a.T @ p_vec + qux.T @ small_k
    x, us = x0, []
    for big_k, small_k in reversed(gains):
        us.append(big_k @ x + small_k)
        x = a @ x + b @ us[-1]
    return np.array(us)


def test_ddp_is_the_lqr_optimum_on_a_mass_spring():
    system, cost = mass_spring()
    unbounded = ActuationBounds(np.array([-np.inf]), np.array([np.inf]))
    x0 = np.zeros(2)
    result = BoxDDP().solve(system, x0, cost, unbounded)
    assert result.converged
    # One Newton step is exact on an LQ problem; the second only confirms it.
    assert result.iterations <= 2
    np.testing.assert_allclose(result.us, lqr(system.a[0], system.b[0], cost, x0), atol=1e-10)


def test_box_ddp_matches_crocoddyl_box_fddp():
    system, cost = mass_spring(60)
    bounds = ActuationBounds(np.array([-0.3]), np.array([1.5]))
    x0 = np.zeros(2)
    ours = BoxDDP(tolerance=1e-12).solve(system, x0, cost, bounds)
    fx, fu = system.derivatives(ours.rollout)
    xs, us, _, _ = solve_frozen(x0, fx, fu, np.zeros((60, 2)), cost, bounds, np.zeros((60, 1)))
    assert np.any(ours.us == 1.5) and np.any(ours.us == -0.3)  # both bounds bind
    np.testing.assert_allclose(ours.us, us, atol=1e-7)
    assert ours.cost == pytest.approx(cost.value(xs, us), rel=1e-12)
    # The same solve with crocoddyl's backward pass in the loop.
    theirs = BoxDDP(tolerance=1e-12, backend="crocoddyl").solve(system, x0, cost, bounds)
    np.testing.assert_allclose(theirs.us, us, atol=1e-7)


def test_controls_never_violate_their_bounds(rng):
    system, cost = mass_spring(50)
    bounds = ActuationBounds(
        np.array([-0.5]), np.array([2.0]), max_change=np.array([0.1]), previous=np.zeros(1)
    )
    guess = rng.uniform(-5.0, 5.0, (50, 1))  # far outside: projected first
    result = BoxDDP(max_iterations=50).solve(system, np.zeros(2), cost, bounds, guess)
    assert result.bound_violation == 0.0
    assert np.all(result.us >= -0.5) and np.all(result.us <= 2.0)
    steps = np.diff(np.vstack([np.zeros((1, 1)), result.us]), axis=0)
    assert np.all(np.abs(steps) <= 0.1 + 1e-12)
    assert np.any(np.isclose(np.abs(steps), 0.1))  # the change bound binds
    assert result.cost < cost.value(*_rollout(system, bounds.project(guess)))


@pytest.mark.parametrize("mu", [0.0, 1e-2])
def test_compiled_backward_pass_is_the_numpy_reference(rng, mu):
    n = 30
    fx = np.tile(np.eye(6), (n, 1, 1))
    fx[:, :3, 3:] = 0.02 * np.eye(3)
    fu = rng.normal(size=(n, 6, 4)) * 1e-3
    xs, us = rng.normal(size=(n + 1, 6)), rng.uniform(0.0, 100.0, (n, 4))
    cost = tracking_cost(rng.normal(size=(n + 1, 3)), n_controls=4, control_weight=1e-6)
    boxes = [(np.zeros(4), np.full(4, 100.0))] * n  # binds at many nodes
    reference = backward_pass(xs, us, fx, fu, cost, boxes, mu)
    compiled = compiled_backward_pass(xs, us, fx, fu, cost, boxes, mu)
    assert np.any(reference.k + us == 100.0) and np.any(reference.k + us == 0.0)
    np.testing.assert_allclose(compiled.k, reference.k, atol=1e-9)
    np.testing.assert_allclose(compiled.feedback, reference.feedback, atol=1e-9)
    assert compiled.predicted(1.0) == pytest.approx(reference.predicted(1.0), rel=1e-12)
    assert compiled.stationarity == pytest.approx(reference.stationarity, rel=1e-12)


def _rollout(system, us):
    r = system.rollout(np.zeros(2), us)
    return r.xs, r.us


@pytest.fixture(scope="module")
def diamond():
    """The coarse Diamond (~1.5k DoFs) at rest, and its condensed dynamics with the
    non-linear part."""
    model = robots.diamond(mesh_size=30.0)
    return model, CondensedDynamics(model, 0.02, nonlinear=True)


def test_condensed_derivatives_are_the_fem_steps(diamond):
    """Fu (Eq. 5.26) is exact: the step is linear in the actuator forces. Fx (Eq. 5.27) with
    the non-linear part is the derivative of the FEM step along the lift, to the change of K
    over the perturbation; the linear part alone misses the stiffness and damping terms."""
    model, dyn = diamond
    us = np.tile([300.0, 0.0, 100.0, 0.0], (10, 1))
    rollout = dyn.rollout(model.rest_state(), us)
    fx, fu = dyn.derivatives(rollout)
    fx_linear, _ = dyn.derivatives(rollout, nonlinear=False)
    k = 8
    state, u = rollout.states[k], us[k]
    base = dyn.effector_state(dyn.step(state, u)[0])
    np.testing.assert_allclose(base, rollout.xs[k + 1], atol=1e-12)
    for j in range(4):
        du = np.zeros(4)
        du[j] = 10.0
        moved = dyn.effector_state(dyn.step(state, u + du)[0])
        np.testing.assert_allclose((moved - base) / 10.0, fu[k][:, j], rtol=1e-8, atol=1e-12)
    space = model.constraint_space(state.positions, model.effectors, with_distance=False)
    ht = space.jacobian_t
    lift = ht @ np.linalg.inv(ht.T @ ht)  # the pseudo-inverse lift of the dynamics
    eps = 1e-5
    for i in range(6):
        d = np.zeros(6)
        d[i] = eps
        perturbed = state.copy()
        perturbed.positions = state.positions + model.body.scatter(lift @ d[:3])
        perturbed.velocities = state.velocities + model.body.scatter(lift @ d[3:])
        fd = (dyn.effector_state(dyn.step(perturbed, u)[0]) - base) / eps
        scale = np.abs(fd).max()
        assert np.abs(fd - fx[k][:, i]).max() <= 1e-2 * scale
        assert np.abs(fd - fx_linear[k][:, i]).max() > 10 * np.abs(fd - fx[k][:, i]).max()


def test_crocoddyl_agrees_on_the_condensed_problem(diamond):
    """On the Diamond's condensed problem frozen along a rollout: with bounds that do not bind,
    Box-FDDP's backward pass gives our gains; with bounds that bind, the two backward passes
    differ (crocoddyl updates the value function as if no control were clamped) but both
    solves reach the same optimum."""
    model, dyn = diamond
    n = 12
    rollout = dyn.rollout(model.rest_state(), np.tile([200.0, 0.0, 0.0, 0.0], (n, 1)))
    fx, fu = dyn.derivatives(rollout, nonlinear=False)
    goal = rollout.xs[0, :3] + [5.0, 0.0, 2.0]
    cost = tracking_cost(np.tile(goal, (n + 1, 1)), n_controls=4, control_weight=1e-5)
    from pliant.trajopt.crocoddyl_backend import backward_pass as crocoddyl_pass

    wide = [(np.full(4, -1e6), np.full(4, 1e6))] * n
    ours = backward_pass(rollout.xs, rollout.us, fx, fu, cost, wide)
    theirs = crocoddyl_pass(rollout.xs, rollout.us, fx, fu, cost, wide)
    np.testing.assert_allclose(theirs.k, ours.k, rtol=1e-6, atol=1e-9 * np.abs(ours.k).max())
    np.testing.assert_allclose(theirs.feedback, ours.feedback, rtol=1e-6, atol=1e-3)
    frozen = LinearDynamics.along(rollout.xs, rollout.us, fx, fu)
    bounds = ActuationBounds(np.zeros(4), np.full(4, 400.0))
    solved = BoxDDP(tolerance=1e-12).solve(frozen, rollout.xs[0], cost, bounds, rollout.us)
    assert np.any(solved.us == 400.0) and np.any(solved.us == 0.0)
    drift = frozen.c
    # Both to the same stopping threshold: crocoddyl's default 1e-9 stops two iterations
    # short on some machines (4e-4 off at one control).
    xs, us, _, _ = solve_frozen(
        rollout.xs[0], fx, fu, drift, cost, bounds, rollout.us, tolerance=1e-12
    )
    np.testing.assert_allclose(solved.us, us, atol=1e-6 * 400.0)
    assert solved.cost == pytest.approx(cost.value(xs, us), rel=1e-9)


def test_diamond_ddp_reaches_a_goal_within_bounds(diamond):
    """A short reach (0.3 s): the full-FEM DDP brings the effector to a goal that forces
    within the bounds reach, and no control leaves its bounds."""
    model, _ = diamond
    dyn = CondensedDynamics(model, 0.02)
    start = model.rest_state()
    n = 15
    target = dyn.rollout(start, np.tile([250.0, 0.0, 0.0, 100.0], (n, 1))).xs[-1, :3]
    cost = tracking_cost(
        np.vstack([np.full((n, 3), np.nan), target]),
        n_controls=4,
        velocity_weight=1e-3,
        control_weight=1e-7,
        terminal_weight=100.0,
    )
    bounds = ActuationBounds(np.zeros(4), np.full(4, 400.0), max_change=np.full(4, 60.0))
    result = BoxDDP(max_iterations=12, tolerance=1e-5).solve(dyn, start, cost, bounds)
    assert result.bound_violation == 0.0
    assert np.linalg.norm(result.xs[-1, :3] - target) < 1.0
    assert result.cost < 0.1 * result.history[0]["cost"]


def test_bad_input_raises_named_errors():
    system, cost = mass_spring(10)
    with pytest.raises(InfeasibleProblemError, match="lower > upper"):
        ActuationBounds(np.array([1.0]), np.array([0.0]))
    with pytest.raises(InfeasibleProblemError, match="max_change"):
        ActuationBounds(np.zeros(1), np.ones(1), max_change=np.zeros(1))
    with pytest.raises(TrajectoryOptimisationError, match="horizon"):
        tracking_cost(np.ones((1, 1)), n_controls=1)
    with pytest.raises(TrajectoryOptimisationError, match=">= 0"):
        tracking_cost(np.ones((5, 1)), n_controls=1, position_weight=-1.0)
    with pytest.raises(TrajectoryOptimisationError, match="> 0"):
        tracking_cost(np.ones((5, 1)), n_controls=1, control_weight=0.0)
    with pytest.raises(TrajectoryOptimisationError, match="max_iterations"):
        BoxDDP(max_iterations=0)
    exploding = LinearDynamics(np.eye(2) * 1e200, np.ones((2, 1)))
    with pytest.raises(TrajectoryOptimisationError, match="diverged"):
        BoxDDP().solve(
            exploding, np.ones(2), cost, ActuationBounds(np.zeros(1), np.ones(1)), np.ones((10, 1))
        )


def test_cli_writes_plots_gif_and_report(tmp_path):
    """``pliant trajopt diamond`` and ``diamond-mpc`` on a coarse mesh and a short horizon."""
    import json

    from typer.testing import CliRunner

    from pliant.cli import app

    runner = CliRunner()
    common = ["--mesh-size", "30", "--settle", "0.2", "--out", str(tmp_path)]
    result = runner.invoke(
        app,
        ["trajopt", "diamond", "--no-nonlinear", "--horizon", "10", "--max-iterations", "2"]
        + ["--frames", "2", *common],
    )
    assert result.exit_code == 0, result.output
    report = json.loads((tmp_path / "diamond.json").read_text())
    assert [r["run"] for r in report["runs"]] == ["linear"]
    assert all(r["bound_violation"] == 0.0 for r in report["runs"])
    for name in ("diamond.png", "diamond.gif"):
        assert (tmp_path / name).stat().st_size > 0
    result = runner.invoke(
        app, ["trajopt", "diamond-mpc", "--horizon", "5", "--steps", "6", *common]
    )
    assert result.exit_code == 0, result.output
    mpc = json.loads((tmp_path / "diamond_mpc.json").read_text())
    assert mpc["bound_violation"] == 0.0 and mpc["loop_rate_hz"] > 0
    result = runner.invoke(app, ["trajopt", "diamond", "--horizon", "0", *common])
    assert result.exit_code == 2 and "horizon" in result.output  # a usage error, before work


def test_change_bound_optimum_against_a_qp_solver():
    """The change bound couples consecutive controls. On the mass-spring the cost is a
    quadratic in u (the rollout is linear in u), J = 1/2 u^T H u + g^T u + c, read from
    rollouts; its optimum with -0.5 <= u <= 2 and |u_k - u_{k-1}| <= 0.1 is ProxQP's.
    Augmenting the state (the change as the control, a plain box) reaches it in a few
    iterations; the nodes' sequential boxes stop slightly above it."""
    from pliant._proxsuite import proxqp

    n = 40
    system, cost = mass_spring(n)
    bounds = ActuationBounds(
        np.array([-0.5]), np.array([2.0]), max_change=np.array([0.1]), previous=np.zeros(1)
    )

    def value(u):
        rollout = system.rollout(np.zeros(2), u.reshape(-1, 1))
        return cost.value(rollout.xs, rollout.us)

    c = value(np.zeros(n))
    eye = np.eye(n)
    hess = np.array([[value(a + b) - value(a) - value(b) + c for b in eye] for a in eye])
    grad = np.array([value(e) - c for e in eye]) - 0.5 * np.diag(hess)
    change = eye - np.eye(n, k=-1)
    qp = proxqp.dense.QP(n, 0, 2 * n)
    qp.settings.eps_abs = 1e-12
    qp.init(
        hess,
        grad,
        None,
        None,
        np.vstack([eye, change]),
        np.concatenate([np.full(n, -0.5), np.full(n, -0.1)]),
        np.concatenate([np.full(n, 2.0), np.full(n, 0.1)]),
    )
    qp.solve()
    reference = value(qp.results.x)
    augmented = BoxDDP(tolerance=1e-12, change_bound="augmented").solve(
        system, np.zeros(2), cost, bounds
    )
    sequential = BoxDDP(max_iterations=200, tolerance=1e-12, change_bound="sequential").solve(
        system, np.zeros(2), cost, bounds
    )
    assert augmented.iterations <= 5 and augmented.bound_violation == 0.0
    assert augmented.cost == pytest.approx(reference, rel=1e-7)
    assert sequential.bound_violation == 0.0
    assert reference <= sequential.cost <= reference * (1 + 1e-4)


def test_a_diverging_fem_rollout_names_its_node(diamond):
    model, _ = diamond
    dyn = CondensedDynamics(model, 0.02)
    huge = np.full((5, 4), 1e7)  # mN: the cables crush the Diamond in one step
    with pytest.raises(DivergenceError, match="node 0 of 5") as info:
        dyn.rollout(model.rest_state(), huge)
    assert info.value.cause == "rollout" and info.value.step == 0
    cost = tracking_cost(np.zeros((6, 3)), n_controls=4)
    bounds = ActuationBounds(np.zeros(4), np.full(4, 1e7))
    with pytest.raises(TrajectoryOptimisationError, match="initial guess"):
        BoxDDP().solve(dyn, model.rest_state(), cost, bounds, huge)


def test_several_effectors_and_selected_axes(diamond):
    """Two effectors, one on x and z only and weighted: the condensed state holds their rows
    (unweighted positions), Fu is still exact, and the DDP lowers the cost."""
    from pliant.constraints.base import EmbeddedPoints
    from pliant.constraints.effector import PositionEffector
    from pliant.model import Model

    base, _ = diamond
    body = base.body
    top = base.effectors[0]
    elbow = PositionEffector(
        EmbeddedPoints(body.mesh, [[0.0, 97.0, 45.0]]),
        body.rest_positions,
        axes=(True, False, True),
        weight=3.0,
        name="elbow",
    )
    model = Model(body, actuators=base.actuators, effectors=[top, elbow], name="two")
    dyn = CondensedDynamics(model, 0.02)
    start = model.rest_state()
    assert dyn.n_state == 10
    x0 = dyn.effector_state(start)
    np.testing.assert_allclose(x0[3:5], elbow.position(start.positions)[0, [0, 2]])
    us = np.tile([200.0, 0.0, 100.0, 0.0], (4, 1))
    rollout = dyn.rollout(start, us)
    _, fu = dyn.derivatives(rollout)
    pushed = us.copy()
    pushed[0, 0] += 10.0
    fd = (dyn.rollout(start, pushed).xs[1] - rollout.xs[1]) / 10.0
    np.testing.assert_allclose(fd, fu[0][:, 0], rtol=1e-8, atol=1e-12)
    goals = np.tile(x0[:5] + [2.0, 0.0, 1.0, 1.0, 0.5], (5, 1))
    cost = tracking_cost(goals, n_controls=4, control_weight=1e-6)
    result = BoxDDP(max_iterations=3).solve(
        dyn, start, cost, ActuationBounds(np.zeros(4), np.full(4, 500.0))
    )
    assert result.cost < result.history[0]["cost"] and result.bound_violation == 0.0


@pytest.mark.parametrize(
    "command", ["stiff-flop", "lianford-spiral", "lianford-pick-place", "lianford-orientation"]
)
def test_scenarios_quick_mode_writes_reports_within_bounds(command, tmp_path) -> None:
    """Each `pliant trajopt SCENARIO --quick` (short horizon, 2 DDP iterations) writes its plot,
    GIF and JSON report; every returned control meets its bounds, the cost did not rise."""
    from pliant.trajopt.runs import run_scenario

    report = run_scenario(
        command, quick=True, frames=2 if command == "stiff-flop" else 0, out=tmp_path
    )
    assert (tmp_path / f"{command}.png").stat().st_size > 0
    assert (tmp_path / f"{command}.json").exists()
    assert report["quick"] and report["runs"]
    for run in report["runs"]:
        assert run["bound_violation"] == 0.0
        low, high = run["actuation_range"]
        assert min(run["bounds"][0]) <= low and high <= max(run["bounds"][1])
        assert run["cost"] <= run["cost_history"][0] + 1e-9
        assert np.isfinite(run["final_error"])
    if command == "stiff-flop":
        assert {r["run"] for r in report["runs"]} == {"stiff-flop-middle", "stiff-flop-tip"}
        assert (tmp_path / "stiff-flop-tip.gif").exists()
