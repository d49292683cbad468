"""The floors only look down: the import contract in pyproject.toml ([tool.importlinter],
docs/concepts/architecture.md) holds for every module of pliant, imports inside functions
included."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).parents[2]


@pytest.mark.skipif(
    shutil.which("lint-imports") is None,
    reason="import-linter not installed (pip install import-linter, or the dev extra)",
)
def test_import_contract_is_kept():
    result = subprocess.run(
        ["lint-imports", "--no-cache"], cwd=ROOT, capture_output=True, text=True, timeout=300
    )
    assert result.returncode == 0, result.stdout + result.stderr


def test_the_package_face_gives_the_core_without_the_learning_extras():
    """`import pliant` imports neither gymnasium nor torch; every name of a package's __all__
    is there (the root's imported on first use)."""
    code = (
        "import sys, pliant\n"
        "heavy = {'gymnasium', 'torch', 'stable_baselines3'} & set(sys.modules)\n"
        "assert not heavy, heavy\n"
        "import pliant.constraints, pliant.fem, pliant.solvers\n"
        "for package in (pliant.fem, pliant.constraints, pliant.solvers):\n"
        "    for name in package.__all__:\n"
        "        getattr(package, name)\n"
        "from pliant import Model, State, TetBody, CableActuator, ImplicitEuler, build_robot\n"
        "assert Model is __import__('pliant.model').model.Model\n"
        "print(sorted(n for n in pliant.__all__ if n not in ('make', 'ENVS', 'load_scene')"
        " and getattr(pliant, n) is None))\n"
    )
    result = subprocess.run(
        [sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=300
    )
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == "[]"
