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


def test_gradient_cost_repeats_interleaved_and_takes_medians():
    row = gradient_cost(two_cable_beam(), np.array([0.5, 0.0]), 4, repeats=3)
    kept = row["all_states_kept"]
    assert row["repeats"] == 3 and len(row["forward_s_each"]) == 3
    assert row["forward_s"] == pytest.approx(np.median(row["forward_s_each"]))
    ratios = np.asarray(kept["gradient_s_each"]) / np.asarray(row["forward_s_each"])
    assert kept["ratio_each"] == pytest.approx(ratios.tolist())
    assert kept["gradient_over_forward"] == pytest.approx(np.median(ratios))
    with pytest.raises(ModelError, match="repeats >= 1"):
        gradient_cost(two_cable_beam(), np.array([0.5, 0.0]), 4, repeats=0)
