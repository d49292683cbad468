"""Result files (issue 61): a series (trajectory, time line) is written at 7 significant digits,
each list of numbers on one line, while single numbers (the registry's figures) keep every
digit; the tracked results stay under the repository's 30 MB."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import numpy as np
import pytest

from pliant.files import SERIES_LENGTH, compact_series, write_results

ROOT = Path(__file__).parents[2]


def test_series_are_rounded_and_figures_kept(tmp_path):
    rng = np.random.default_rng(0)
    trajectory = rng.normal(size=(40, 3))
    data = {
        "figure": 0.12345678901234567,
        "start": [67.99999999999996, -1.14347259141586e-16, 3.1822164948453637],
        "trajectory": trajectory,
        "times": [0.1 * k for k in range(SERIES_LENGTH)],
        "steps": [{"reward": float(r)} for r in rng.normal(size=SERIES_LENGTH)],
        "flags": [True] * SERIES_LENGTH,
        "count": np.int64(3),
    }
    path = tmp_path / "result.json"
    write_results(path, data)
    back = json.loads(path.read_text())
    assert back["figure"] == data["figure"] and back["start"] == data["start"]
    assert [s["reward"] for s in back["steps"]] == [s["reward"] for s in data["steps"]]
    assert back["flags"] == data["flags"] and back["count"] == 3
    np.testing.assert_allclose(back["trajectory"], trajectory, rtol=5e-7, atol=0)
    assert back["trajectory"] != trajectory.tolist()  # rounded: 7 digits, not 17
    assert all(len(f"{x!r}".lstrip("-").replace(".", "").lstrip("0")) <= 7 for x in back["times"])
    text = path.read_text()
    assert "\n" not in text[text.index('"times"') :].split("]")[0]  # one line a list
    assert list(tmp_path.iterdir()) == [path]  # written atomically: no temporary left
    write_results(path, {"trajectory": trajectory})
    assert path.stat().st_size < 0.5 * len(
        json.dumps({"trajectory": trajectory.tolist()}, indent=1)
    )


def test_compact_series_leaves_what_is_not_a_series():
    assert compact_series({"a": [1.123456789] * 3}) == {"a": [1.123456789] * 3}
    mixed = ["x"] + [1.123456789] * 40
    assert compact_series(mixed) == mixed
    assert compact_series([[1.123456789] * 20] * 2) == [[1.123457] * 20] * 2
    assert compact_series([float("nan")] * 40)[0] != compact_series([float("nan")] * 40)[0]


def test_tracked_results_stay_under_30_mb():
    listing = subprocess.run(
        ["git", "ls-files", "experiments/results"], cwd=ROOT, capture_output=True, text=True
    )
    if listing.returncode != 0 or not listing.stdout:
        pytest.skip("not a git checkout: the tracked results are not known")
    sizes = [
        (ROOT / name).stat().st_size for name in listing.stdout.split() if (ROOT / name).exists()
    ]
    assert sum(sizes) <= 30e6, f"tracked results hold {sum(sizes) / 1e6:.1f} MB"
