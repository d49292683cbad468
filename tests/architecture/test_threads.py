"""Thread settings: ``import pliant`` applies configure_threads' defaults, the environment
overrides them, and configure_threads changes them later or refuses what it does not know."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).parents[2]
SETTINGS = (
    "OMP_WAIT_POLICY",
    "PLIANT_BLAS_THREADS",
    "OPENBLAS_NUM_THREADS",
    "NUMBA_THREADING_LAYER",
)
PROBE = """
import json, os, numba
numba_default = list(numba.config.THREADING_LAYER_PRIORITY)
import pliant
from threadpoolctl import threadpool_info

def blas():
    return sorted({p["num_threads"] for p in threadpool_info() if p["user_api"] == "blas"})

out = {"layers": list(numba.config.THREADING_LAYER_PRIORITY), "numba_default": numba_default,
       "wait": os.environ["OMP_WAIT_POLICY"], "blas": blas()}
if os.environ.get("PROBE_CHANGE"):
    out["applied"] = pliant.configure_threads(blas_threads=2, omp_wait_policy="active")
    out["blas_after"], out["wait_after"] = blas(), os.environ["OMP_WAIT_POLICY"]
    out["refused"] = []
    for bad in ({"blas_threads": 0}, {"omp_wait_policy": "spin"},
                {"threading_layers": ("gpu",)}, {"torch_threads": True}):
        try:
            pliant.configure_threads(**bad)
        except pliant.errors.ThreadSettingError as exc:
            out["refused"].append(str(exc).split(":")[0])
print(json.dumps(out))
"""


def _probe(**env: str) -> dict:
    clean = {k: v for k, v in os.environ.items() if k not in SETTINGS}
    result = subprocess.run(
        [sys.executable, "-c", PROBE],
        cwd=ROOT,
        env={**clean, **env},
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert result.returncode == 0, result.stderr
    return json.loads(result.stdout)


def test_import_applies_the_defaults_and_configure_threads_changes_them():
    found = _probe(PROBE_CHANGE="1")
    assert found["layers"][0] == "omp" and found["wait"] == "PASSIVE" and found["blas"] == [1]
    assert found["applied"]["blas_threads"] == 2 and found["wait_after"] == "ACTIVE"
    if (os.cpu_count() or 1) >= 2:
        assert found["blas_after"] == [2]
    assert found["refused"] == [
        "blas_threads",
        "omp_wait_policy",
        "threading_layers",
        "torch_threads",
    ]


def test_the_environment_overrides_the_defaults():
    """The user's OMP_WAIT_POLICY, NUMBA_THREADING_LAYER and OpenBLAS threads stand."""
    found = _probe(OMP_WAIT_POLICY="ACTIVE", NUMBA_THREADING_LAYER="workqueue")
    assert found["wait"] == "ACTIVE" and found["layers"] == found["numba_default"]
    threads = min(2, os.cpu_count() or 1)
    assert _probe(OPENBLAS_NUM_THREADS=str(threads))["blas"] == [threads]
    if threads == 2:
        assert _probe(PLIANT_BLAS_THREADS="keep")["blas"] != [1]
        assert _probe(PLIANT_BLAS_THREADS="2")["blas"] == [2]
