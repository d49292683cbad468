"""The gradient's cost report (`pliant bench --gradient`): it times what it says, and refuses
what it cannot time."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import two_cable_beam

from pliant.diff.cost import gradient_cost
from pliant.errors import ModelError


def test_gradient_cost_times_a_rollout_and_its_gradient():
    row = gradient_cost(two_cable_beam(), np.array([0.5, 0.0]), 9)
    assert row["steps"] == 9 and row["forward_s"] > 0.0
    kept, checkpointed = row["all_states_kept"], row["checkpoints_sqrt_T"]
    assert kept["gradient_over_forward"] == pytest.approx(kept["gradient_s"] / row["forward_s"])
    # every state kept: one forward pass; checkpoints every 3 steps: each segment again
    assert kept["solver_steps"] < checkpointed["solver_steps"]
    assert checkpointed["states_held"] < kept["states_held"]


def test_gradient_cost_refuses_commands_of_another_shape():
    with pytest.raises(ModelError, match="one command per actuator"):
        gradient_cost(two_cable_beam(), np.array([0.5]), 9)
