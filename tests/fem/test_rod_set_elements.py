"""RodBody.set_elements: a rod's elements changed in place between steps (pliant.fem.instruments
slides instruments along a rod's nodes)."""

from __future__ import annotations

import numpy as np
import pytest

from pliant.errors import ModelError
from pliant.fem.material import Material
from pliant.fem.rod import RodBody, RodSection


def _rod() -> RodBody:
    points = np.column_stack([np.linspace(0.0, 10.0, 6), np.zeros(6), np.zeros(6)])
    return RodBody(points, RodSection.circle(0.5), Material(1.0e3, 0.3), total_mass=1.0)


def _values(rod: RodBody) -> list[np.ndarray]:
    return [
        rod.lengths.copy(),
        rod._elements[5].copy(),
        rod._elements[6].copy(),
        rod.gamma0.copy(),
        rod.kappa0.copy(),
        rod.node_masses.copy(),
    ]


def test_its_own_values_leave_the_rod_as_it_was_and_others_change_its_forces() -> None:
    rod, same = _rod(), _rod()
    rng = np.random.default_rng(3)
    x = rod.rest_positions + 0.05 * rng.standard_normal(rod.rest_positions.shape)
    before = rod.revision
    rod.set_elements(*_values(same))
    assert rod.revision == before + 1
    np.testing.assert_array_equal(rod.linearise(x).forces, same.linearise(x).forces)
    np.testing.assert_array_equal(rod.mass_data, same.mass_data)
    values = _values(same)
    values[1][:] = 0.0  # no elasticity: no elastic forces
    values[2][:] = 0.0
    values[5] *= 2.0
    rod.set_elements(*values)
    assert np.abs(rod.linearise(x).forces).max() == 0.0
    np.testing.assert_allclose(rod.mass_data, 2.0 * same.mass_data)


def test_bad_values_are_model_errors() -> None:
    rod = _rod()
    values = _values(rod)
    with pytest.raises(ModelError, match="lengths"):
        rod.set_elements(values[0][:-1], *values[1:])
    values[0][2] = 0.0
    with pytest.raises(ModelError, match="lengths must be > 0"):
        rod.set_elements(*values)
