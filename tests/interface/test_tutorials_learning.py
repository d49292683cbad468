"""The learning tutorials (training, the condensed models, the graph, planning, the
proxy's transfer, model reduction, the environment) run in their quick settings
(``PLIANT_TUTORIAL_QUICK=1``), so that they never rot."""

from __future__ import annotations

import pytest
from conftest import run_tutorial, tutorials


@pytest.mark.parametrize("script", tutorials(learning=True), ids=lambda p: p.stem)
def test_learning_tutorial_runs(script, tmp_path):
    run_tutorial(script, tmp_path)
