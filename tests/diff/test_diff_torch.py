"""pliant.diff.torch: torch's backward through a step and a rollout equals the NumPy adjoint
(and, chained through a small torch map, central differences)."""

from __future__ import annotations

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from test_diff import DT, beam, perturbed_state, relative_error  # noqa: E402

from pliant.diff import PointTracking, StepAdjoint, rollout_gradient  # noqa: E402
from pliant.diff import torch as pliant_torch  # noqa: E402
from pliant.solvers.implicit_euler import ImplicitEuler  # noqa: E402


def test_step_backward_is_the_adjoint():
    rng = np.random.default_rng(5)
    model = beam()
    state = perturbed_state(model, rng)
    solver = ImplicitEuler(model, DT, tangent="fresh")
    q = torch.tensor(state.positions, requires_grad=True)
    v = torch.tensor(state.velocities, requires_grad=True)
    c = torch.tensor([1.0, 5.0], dtype=torch.float64, requires_grad=True)
    wq, wv = rng.standard_normal(q.shape), rng.standard_normal(q.shape)
    q1, v1 = pliant_torch.step(model, solver, state, c, q, v)
    (torch.sum(torch.tensor(wq) * q1) + torch.sum(torch.tensor(wv) * v1)).backward()
    new = ImplicitEuler(model, DT, tangent="fresh").step(state.copy(), np.array([1.0, 5.0]))
    ref = StepAdjoint(model, DT, state, np.array([1.0, 5.0]), new).vjp(wq, wv, ("controls",))
    assert np.allclose(q.grad.numpy(), ref["positions"], rtol=1e-12, atol=1e-12)
    assert np.allclose(v.grad.numpy(), ref["velocities"], rtol=1e-12, atol=1e-12)
    assert np.allclose(c.grad.numpy(), ref["controls"], rtol=1e-12, atol=0)


def test_rollout_backward_matches_numpy_and_finite_differences():
    """A torch loss of the tip's trajectory, through a torch map from 2 numbers to the 6-step
    command sequence, and E as a tensor."""
    n_steps = 6
    model = beam()
    solver = ImplicitEuler(model, DT, tangent="fresh")
    rest = model.body.rest_positions
    from pliant.constraints.base import EmbeddedPoints

    tip = EmbeddedPoints.at_nodes(np.flatnonzero(np.isclose(rest[:, 0], 60.0)))
    goal = tip.positions(rest) + np.array([0.0, 0.0, 3.0])
    ramp = torch.linspace(0.2, 1.0, n_steps, dtype=torch.float64)

    def controls_of(theta):
        return torch.stack([theta[0] * ramp, theta[1] + 0.0 * ramp], dim=1)

    def loss_of(theta, young):
        points = pliant_torch.rollout(
            model,
            solver,
            model.rest_state(),
            controls_of(theta),
            parameters={"young_modulus": young},
            points=tip,
        )
        return 0.5 * torch.sum((points - torch.tensor(goal)) ** 2)

    theta = torch.tensor([2.0, 5.0], dtype=torch.float64, requires_grad=True)
    young = torch.tensor(200.0, dtype=torch.float64, requires_grad=True)
    loss = loss_of(theta, young)
    loss.backward()
    ref = rollout_gradient(
        model,
        solver,
        model.rest_state(),
        controls_of(theta).detach().numpy(),
        PointTracking(tip, goal, n_steps=n_steps),
        wrt=("controls", "young_modulus"),
    )
    assert loss.item() == pytest.approx(ref.value, rel=1e-13)
    assert young.grad.item() == pytest.approx(ref.gradients["young_modulus"], rel=1e-10)
    expected = (ref.gradients["controls"][:, 0] * ramp.numpy()).sum()
    assert theta.grad[0].item() == pytest.approx(expected, rel=1e-10)
    with torch.no_grad():
        moved = [
            float(loss_of(theta + torch.tensor([e, 0.0], dtype=torch.float64), young))
            for e in (1e-3, -1e-3)
        ]
    assert relative_error((moved[0] - moved[1]) / 2e-3, theta.grad[0].item()) < 1e-6
