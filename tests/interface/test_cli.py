"""The command line: ``run``, ``inverse`` and ``bench`` write their outputs; bad input fails
with a message that names the problem."""

from __future__ import annotations

import json

import imageio.v3 as iio
import numpy as np
import pytest
from typer.testing import CliRunner

from pliant.cli import app

runner = CliRunner()


def _invoke(*args: str):
    result = runner.invoke(app, list(args))
    return result, result.output


def test_run_writes_gif_png_and_vtu_series(tmp_path) -> None:
    result, output = _invoke(
        "run", "finger", "--duration", "0.05", "--frames", "2", "--out", str(tmp_path)
    )
    assert result.exit_code == 0, output
    folder = tmp_path / "finger"
    gif, png, pvd = folder / "finger.gif", folder / "finger.png", folder / "finger.pvd"
    for path in (gif, png, pvd):
        assert path.is_file() and path.stat().st_size > 0, path
    frames = iio.imread(gif, index=None)
    assert frames.ndim == 4 and frames.shape[0] >= 2
    image = iio.imread(png)
    assert np.any(image[..., :3] != image[0, 0, :3])
    series = sorted(folder.glob("finger_*.vtu"))
    assert len(series) == frames.shape[0]
    assert pvd.read_text().count("<DataSet") == len(series)
    assert "5 steps" in output


def test_run_writes_the_requested_number_of_frames(tmp_path) -> None:
    """--frames is 'frames in the GIF and VTU series': 5 steps and 2 frames give 2 frames."""
    result, output = _invoke(
        "run", "finger", "--duration", "0.05", "--frames", "2", "--out", str(tmp_path)
    )
    assert result.exit_code == 0, output
    assert iio.imread(tmp_path / "finger" / "finger.gif", index=None).shape[0] == 2


def test_inverse_prints_errors_and_writes_reports(tmp_path) -> None:
    result, output = _invoke(
        "inverse", "diamond", "--goals", "2", "--max-steps", "10", "--out", str(tmp_path)
    )
    assert result.exit_code == 0, output
    assert "error: mean" in output
    folder = tmp_path / "diamond"
    report = json.loads((folder / "diamond_circle.json").read_text())
    assert report["robot"] == "diamond" and report["trajectory"] == "circle"
    errors = np.array(report["errors"])
    assert errors.shape == (2,) and np.all(np.isfinite(errors))
    assert report["max_error"] == pytest.approx(errors.max())
    for name in ("diamond_circle.png", "diamond_circle.gif"):
        assert (folder / name).stat().st_size > 0, name


def test_bench_quick_writes_results(tmp_path, monkeypatch) -> None:
    """A smoke run (5 s measured); the lead's bench tests check the figures themselves. Run
    where the reference SOFA meshes are not found, so that it does not depend on the checkout
    next to this one (bench then uses Pliant's own meshes). One environment is timed (all
    eighteen, at three time steps each, is the bench's job, not the test's)."""
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("PLIANT_REFERENCE_MESHES", raising=False)
    out = tmp_path / "bench.json"
    result, output = _invoke(
        "bench",
        "--quick",
        "--repeats",
        "1",
        "--steps",
        "3",
        "--batch",
        "1,2",
        "--envs",
        "Diamond",
        "--out",
        str(out),
    )
    assert result.exit_code == 0, output
    envs = json.loads((tmp_path / "envs.json").read_text())["environments"]
    assert [(r["env"], r["dt"]) for r in envs] == [("Diamond", dt) for dt in (0.01, 0.02, 0.03)]
    assert all(r["stable"] and r["real_time_factor"] > 0.0 for r in envs), envs
    report = json.loads(out.read_text())
    assert report["scenes"]
    for scene in report["scenes"]:
        assert scene["steps_per_s"] > 0.0 and len(scene["repeats"]) == 1, scene
    assert report["inverse_step_ms"] > 0.0
    # The host it ran on, so a slower host can be told from a slower Pliant.
    for host in (report["host_before"], report["host_after"]):
        assert host["cpu_model"] and host["cpus"] >= 1
        assert len(host["load_average_1_5_15_min"]) == 3
    # Each cantilever: the default's error against the exact step over 1 s, and where the
    # time of a step goes (the parts sum to at most the step).
    cantilever = next(s for s in report["scenes"] if s["scene"] == "cantilever-240")
    error = cantilever["extra"]["default_error"]
    assert error["steps"] == 100 and 0.0 <= error["error_end_mm"] < 0.01 * error["motion_max_mm"]
    parts = cantilever["extra"]["breakdown_lagged"]
    assert parts["forces"] > 0.0 and parts["solves"] > 0.0
    assert parts["forces"] + parts["solves"] <= parts["total"] * 1.5
    rows = report["batched"]["cantilever-240"]
    assert [r["copies"] for r in rows] == [1, 2]
    assert all(r["batched"] > 0.0 and r["single_loop"] > 0.0 for r in rows)


@pytest.mark.parametrize("command", ["run", "inverse"])
def test_unknown_robot_fails_with_a_clear_message(command, tmp_path) -> None:
    result, output = _invoke(command, "octopus", "--out", str(tmp_path))
    assert result.exit_code != 0
    assert "unknown robot 'octopus'" in output
    assert "diamond" in output and "trunk" in output
    assert "Traceback" not in output
    assert not any(tmp_path.iterdir())


def test_bad_options_fail_without_traceback(tmp_path) -> None:
    for args in (
        ["run", "finger", "--solver", "explicit", "--out", str(tmp_path)],
        ["inverse", "diamond", "--trajectory", "square", "--out", str(tmp_path)],
    ):
        result, output = _invoke(*args)
        assert result.exit_code != 0, args
        assert not isinstance(result.exception, Exception) or isinstance(
            result.exception, SystemExit
        ), output
