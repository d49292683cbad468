"""The floors only look down: the import contract in pyproject.toml ([tool.importlinter],
docs/concepts/architecture.md) holds for every module of pliant, imports inside functions
included."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).parents[1]


@pytest.mark.skipif(
    shutil.which("lint-imports") is None,
    reason="import-linter not installed (pip install import-linter, or the dev extra)",
)
def test_import_contract_is_kept():
    result = subprocess.run(
        ["lint-imports", "--no-cache"], cwd=ROOT, capture_output=True, text=True, timeout=300
    )
    assert result.returncode == 0, result.stdout + result.stderr
