"""Every other tutorial (the first robot, actuators, contact, inverse control,
trajectory optimisation, gradients) run in their quick settings
(``PLIANT_TUTORIAL_QUICK=1``), so that they never rot."""

from __future__ import annotations

import pytest
from conftest import run_tutorial, tutorials


@pytest.mark.parametrize("script", tutorials(learning=False), ids=lambda p: p.stem)
def test_simulation_tutorial_runs(script, tmp_path):
    run_tutorial(script, tmp_path)
