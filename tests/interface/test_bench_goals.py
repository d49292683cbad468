"""`pliant bench --goals`: issue #62's goals read from the result files, met or missed."""

from __future__ import annotations

import io
import json

import pytest
from rich.console import Console

from pliant.bench.goals import goal_rows, report_goals
from pliant.errors import CorruptFileError


def _write(folder, name, data):
    (folder / name).write_text(json.dumps(data))


def test_goals_are_read_from_the_files_and_judged(tmp_path):
    _write(
        tmp_path,
        "bench.json",
        {
            "scenes": [
                {"scene": "trunk", "policy": "lagged", "steps_per_s": 2500.0, "sofa": 243.8},
                {"scene": "trunk", "policy": "fresh", "steps_per_s": 600.0, "sofa": 243.8},
                {"scene": "trunk", "policy": "pcg", "steps_per_s": 1300.0, "sofa": 243.8},
                {"scene": "gripper", "policy": "lagged", "steps_per_s": 200.0, "sofa": None},
            ],
            "mujoco_flex_peer": {
                "rows": [{"scene": "cantilever-240", "mujoco": {"converged": {"ratio": 2.9}}}]
            },
        },
    )
    _write(
        tmp_path,
        "envs.json",
        {
            "environments": [
                {"env": "Trunk", "dt": 0.01, "real_time_factor": 12.0, "stable": True},
                {"env": "Trunk", "dt": 0.02, "real_time_factor": 1.0, "stable": True},
                {"env": "Multigait", "dt": 0.01, "real_time_factor": 2.5, "stable": True},
                {"env": "TrunkPush", "dt": 0.01, "stable": False, "note": "DivergenceError"},
            ]
        },
    )
    rows = {(r["goal"], r["subject"]): r for r in goal_rows(tmp_path)}
    default = rows[("default step / SOFA", "trunk")]
    assert default["measured"] == pytest.approx(2500.0 / 243.8) and default["met"]
    exact = rows[("exact step / SOFA", "trunk")]  # the faster exact policy counts
    assert exact["measured"] == pytest.approx(1300.0 / 243.8) and exact["met"]
    assert ("default step / SOFA", "gripper") not in rows  # no SOFA figure, no goal
    mujoco = rows[("Pliant / MuJoCo flex", "cantilever-240")]
    assert mujoco["met"] is False and "mujoco_flex_peer" in mujoco["breakdown"]
    assert rows[("real-time factor at dt 0.01", "Trunk")]["met"]
    assert rows[("real-time factor at dt 0.01", "Multigait")]["target"] == 2.0
    assert rows[("real-time factor at dt 0.01", "Multigait")]["met"]
    diverged = rows[("real-time factor at dt 0.01", "TrunkPush")]
    assert diverged["met"] is None and diverged["note"] == "DivergenceError"
    assert not any(goal == "SAC training steps/s vs SB3's" for goal, _ in rows)  # not measured

    written = report_goals(tmp_path, console=Console(file=io.StringIO()))
    assert json.loads((tmp_path / "goals.json").read_text())["goals"] == written


def test_sac_goal_compares_pliants_updates_with_sb3s(tmp_path):
    runs = [
        {"algo": "SAC", "fast_updates": False, "cpu_bound_steps_per_s": 10.0},
        {"algo": "SAC", "fast_updates": True, "cpu_bound_steps_per_s": 31.0},
        {"algo": "PPO", "fast_updates": True, "cpu_bound_steps_per_s": 99.0},
    ]
    _write(tmp_path, "learner_training.json", {"training": runs})
    (row,) = goal_rows(tmp_path)
    assert row["measured"] == pytest.approx(3.1) and row["met"]


def test_no_results_and_bad_files_are_named(tmp_path):
    console = Console(file=io.StringIO())
    with pytest.raises(FileNotFoundError, match="no bench.json"):
        report_goals(tmp_path, console=console)
    (tmp_path / "bench.json").write_text("{not json")
    with pytest.raises(CorruptFileError, match="bench.json"):
        goal_rows(tmp_path)
