"""pliant.diff.policy: a closed-loop episode's gradient with respect to a policy's parameters
(back-propagation through time, each step's adjoint) against central differences of the same
episodes run forward."""

from __future__ import annotations

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from test_diff import DT, beam, relative_error  # noqa: E402

from pliant.constraints.base import EmbeddedPoints  # noqa: E402
from pliant.diff.policy import closed_loop, embedded_positions  # noqa: E402
from pliant.errors import ModelError  # noqa: E402
from pliant.solvers.implicit_euler import ImplicitEuler  # noqa: E402


def test_closed_loop_gradient_against_finite_differences():
    """A linear feedback of the tip's displacement onto both cables (one in displacement
    mode, one in force mode), 3 control steps of 2 solver steps each."""
    model = beam()
    rest = model.body.rest_positions
    tip = EmbeddedPoints.at_nodes(np.flatnonzero(np.isclose(rest[:, 0], 60.0))[:1])
    tip_rest = torch.as_tensor(tip.positions(rest)[0])
    solver = ImplicitEuler(model, DT, tangent="fresh")
    rng = np.random.default_rng(11)
    gain0 = 0.05 * rng.standard_normal((2, 3))
    bias0 = np.array([0.5, 4.0])

    def loss(gain, bias):
        def policy(q, v, n):
            return bias + gain @ (embedded_positions(tip, q)[0] - tip_rest)

        episode = closed_loop(model, solver, model.rest_state(), policy, 3, substeps=2)
        return sum(torch.sum(embedded_positions(tip, q)[0] - tip_rest) for q, _ in episode)

    gain = torch.tensor(gain0, requires_grad=True)
    bias = torch.tensor(bias0, requires_grad=True)
    loss(gain, bias).backward()
    direction = rng.standard_normal(gain0.shape)
    checks = (
        (float(bias.grad[0]), lambda e: (gain0, bias0 + [e, 0.0])),
        (float(bias.grad[1]), lambda e: (gain0, bias0 + [0.0, e])),
        (float(np.sum(gain.grad.numpy() * direction)), lambda e: (gain0 + e * direction, bias0)),
    )
    eps = 1e-4
    with torch.no_grad():
        for exact, moved in checks:
            up, down = (float(loss(*map(torch.as_tensor, moved(s * eps)))) for s in (1, -1))
            assert relative_error((up - down) / (2 * eps), exact) < 1e-6


def test_closed_loop_refuses_bad_step_counts():
    model = beam()
    solver = ImplicitEuler(model, DT, tangent="fresh")
    with pytest.raises(ModelError, match="n_steps"):
        closed_loop(model, solver, model.rest_state(), lambda q, v, n: torch.zeros(2), 0)
