"""The proxy RL studies' shared settings and rows (pliant.transfer.rl, fem_rl, reports, batch):
the settings a study asks for or is refused, the configurations they make, the degraded
proxies' draws, one episode's summary, the FEM environment's keywords, and the reports read back
into rows."""

from __future__ import annotations

import json
import sys

import gymnasium as gym
import numpy as np
import pytest

from pliant.errors import TrainingError
from pliant.proxy.builders import MULTIGAIT_PARAMETERS, TRUNK_PARAMETERS
from pliant.transfer import batch, fem_rl, reports, rl


def test_settings_name_the_robot_and_algorithm_they_lack():
    assert rl.settings("trunk")["env_id"] == "pliant/TrunkPushProxy-v0"
    sac = rl.settings("trunk", "SAC")
    assert sac["hyperparams"]["buffer_size"] == 100_000 and sac["eval_freq"] == 1000
    with pytest.raises(TrainingError, match="'snake'"):
        rl.settings("snake")
    with pytest.raises(TrainingError, match="SAC settings for the multigait"):
        rl.settings("multigait", "SAC")


def test_rl_config_merges_the_hyperparameters_key_by_key():
    config = rl.rl_config(
        "trunk",
        "pliant/TrunkPushProxy-v0",
        {"bend_limit": 0.2},
        500,
        3,
        hyperparams={"n_epochs": 5, "policy_kwargs": {"log_std_init": -1.0}},
    )
    assert config.total_timesteps == 500 and config.seed == 3 and config.n_envs == 1
    assert config.hyperparams["n_epochs"] == 5
    # the settings' network kept beside the new initial spread
    assert config.hyperparams["policy_kwargs"] == {"net_arch": [128, 128], "log_std_init": -1.0}
    assert "n_epochs" not in rl.SETTINGS["trunk"]["hyperparams"]  # the settings untouched
    assert config.checkpoint_freq == config.eval_freq == 1000


def test_degraded_parameters_are_the_seeds_draw_within_the_level():
    one, again = rl.degraded("trunk", 0.1, seed=4), rl.degraded("trunk", 0.1, seed=4)
    assert one == again and one != rl.degraded("trunk", 0.1, seed=5)
    assert set(one) == set(TRUNK_PARAMETERS)
    for key, value in one.items():
        assert abs(value / TRUNK_PARAMETERS[key] - 1.0) <= 0.1 + 1e-12
    assert set(rl.degraded("multigait", 0.01, seed=0)) == set(MULTIGAIT_PARAMETERS)
    assert rl.degraded("trunk", 0.5, 0, reference={"k": 2.0})["k"] != 2.0


class _Reach(gym.Env):
    """Steps towards 0 by the action; solved (terminated) under 0.5."""

    observation_space = gym.spaces.Box(-10.0, 10.0, (1,))
    action_space = gym.spaces.Box(-1.0, 1.0, (1,))

    def reset(self, seed=None, options=None):
        super().reset(seed=seed)
        self.x = 3.0
        return np.array([self.x]), {}

    def step(self, action):
        self.x -= float(action[0])
        return np.array([self.x]), -abs(self.x), abs(self.x) < 0.5, False, {}

    def distance(self):
        return abs(self.x)


def test_episode_sums_the_rewards_to_the_end():
    row = rl.episode(_Reach(), lambda obs, k: np.array([1.0]), seed=0)
    assert row == {"return": -3.0, "length": 3, "distance": 0.0, "solved": True}


def test_fem_keywords_check_the_time_step_and_cable_step():
    assert fem_rl.fem_kwargs(False) == fem_rl.FEM_KWARGS
    assert fem_rl.fem_kwargs(True)["planar"] is True
    coarse = fem_rl.fem_kwargs(False, dt=0.03, cable_step=3.0)
    assert coarse["substeps"] == 10 and coarse["max_displacement_change"] == 3.0
    with pytest.raises(TrainingError, match="does not divide"):
        fem_rl.fem_kwargs(False, dt=0.07)
    with pytest.raises(TrainingError, match="cable step"):
        fem_rl.fem_kwargs(False, cable_step=float("nan"))
    assert fem_rl.suffix("SAC", 1, planar=True) == "_sac_planar_seed1"
    assert (
        fem_rl.goal_kwargs((25.0, 0.0))["goal_low"] == fem_rl.goal_kwargs((25.0, 0.0))["goal_high"]
    )


def test_summary_counts_the_solved_and_refuses_none():
    out = fem_rl.summary([2.0, 10.0, 4.0, 12.0])
    assert out == {
        "mean_final_distance_mm": 7.0,
        "median_final_distance_mm": 7.0,
        "solved_under_8mm": 0.5,
    }
    with pytest.raises(TrainingError, match="no final distances"):
        fem_rl.summary([])


def _transfer_report(folder, proxy=10.0, fem=8.0):
    folder.mkdir(parents=True)
    steps = [
        {"action": a, "tracking_error": t, "proxy_reward": proxy / 2, "fem_reward": fem / 2}
        for a, t in ((1, 0.5), (2, 1.5))
    ]
    report = {
        "steps": steps,
        "proxy_return": proxy,
        "fem_return": fem,
        "failed_inverse_steps": 0,
        "wall_time_s": 3.21,
    }
    (folder / "multigait_transfer.json").write_text(json.dumps(report))


def test_transfer_row_reads_a_transfer_and_reports_a_missing_one(tmp_path, capsys):
    _transfer_report(tmp_path / "a")
    row = reports.transfer_row("a", tmp_path / "a", ["--steps", "2"])
    assert row["actions"] == [1, 2] and row["fem_over_proxy"] == 0.8
    assert row["relative_difference"] == 0.25 and row["tracking_mean_mm"] == 1.0
    assert reports.transfer_row("b", tmp_path / "b", []) is None
    assert "missing" in capsys.readouterr().err


def test_proxy_and_fem_sides_read_each_seeds_reports(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    for s in range(2):
        name = reports.seeded("rl_trunk_x", s)
        (reports.PROXY / name).mkdir(parents=True)
        learned = {"mean_final_distance_mm": 3.0 + s, "solved": 0.5}
        own = {"evaluation": {"learned": learned}, "training_seconds": 10.0}
        (reports.PROXY / name / "report.json").write_text(json.dumps(own))
        moved = {"fem": {"mean_final_distance_mm": 6.0, "solved_under_8mm": 0.7}}
        (reports.FEM / f"report_{name}.json").write_text(json.dumps(moved)) if s else None
        folder = reports.FEM / reports.seeded("std1", s)
        folder.mkdir(parents=True)
        direct = {"mean_final_distance_mm": 9.0, "solved_under_8mm": 0.2, "training_seconds": 5}
        both = {"rl_on_fem": direct, "proxy_pipeline": {"policy": f"x/{name}", **moved}}
        (folder / "report.json").write_text(json.dumps(both))
    rows = reports.proxy_side("_x", seeds=range(2))
    assert [r["on_proxy_mm"] for r in rows] == [3.0, 4.0]
    assert reports.mean(rows, "on_fem_mm") == 6.0
    assert rows[0]["proxsuite_build"] == reports.EARLIER_BUILD  # the report did not say
    assert reports.fem_side("_std1", seeds=range(2))[1]["on_fem_solved"] == 0.2
    with pytest.raises(FileNotFoundError, match="no transfer of rl_trunk_y"):
        reports.transferred("rl_trunk_y", 0)


def test_run_jobs_runs_every_command(tmp_path):
    made = [tmp_path / f"{k}.txt" for k in range(3)]
    batch.run_jobs([[sys.executable, "-c", f"open({str(m)!r}, 'w')"] for m in made], 2, None)
    assert all(m.exists() for m in made)


def test_run_transfers_skips_the_folders_already_done(tmp_path, monkeypatch):
    ran = []
    monkeypatch.setattr(batch, "run_jobs", lambda jobs, workers, env: ran.extend(jobs))
    _transfer_report(tmp_path / "done")
    batch.run_transfers([(["--steps", "8"], tmp_path / "done"), ([], tmp_path / "new")], 2)
    assert ran == [["pliant", "proxy", "transfer", "multigait", "--out", str(tmp_path / "new")]]
