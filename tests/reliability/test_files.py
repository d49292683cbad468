"""Files Pliant writes and reads back, damaged (issue 64): an empty, truncated or random-bytes
checkpoint is skipped by ``--resume`` for the newest intact one (a warning names it), a run
with none intact stops with a CorruptFileError naming the damage, ``pliant eval`` given a file
that is not a model says so in one line, and a write killed half-way leaves the previous file
whole."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap
import warnings
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("torch")

from fault_injection import DAMAGE, damage  # noqa: E402
from typer.testing import CliRunner  # noqa: E402

from pliant.cli import app  # noqa: E402
from pliant.errors import CheckpointWarning, CorruptFileError  # noqa: E402
from pliant.files import check_manifest, read_checked, write_manifest  # noqa: E402
from pliant.learn import TrainConfig, train  # noqa: E402
from pliant.learn.callbacks import check_checkpoint, intact_checkpoint  # noqa: E402
from pliant.learn.evaluate import load_policy  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def run(tmp_path_factory) -> Path:
    """A PPO run on the toy task with checkpoints at steps 100, 200 and 300."""
    folder = tmp_path_factory.mktemp("files") / "run"
    config = TrainConfig(
        env_id="pliant-test/PointReach-v0",
        algo="PPO",
        total_timesteps=300,
        n_envs=1,
        vec_env="dummy",
        eval_freq=0,
        eval_episodes=0,
        checkpoint_freq=100,
        keep_checkpoints=10,
        video_episodes=0,
        normalize=True,
        seed=1,
        hyperparams={"policy": "MlpPolicy", "n_steps": 50, "batch_size": 25},
    )
    train(config, folder)
    return folder


def _copy(run: Path, tmp_path: Path) -> Path:
    import shutil

    shutil.copytree(run, tmp_path / "run")
    return tmp_path / "run"


@pytest.mark.parametrize("how", DAMAGE)
@pytest.mark.parametrize("name", ["model.zip", "state.pkl", "vecnormalize.pkl", "manifest.json"])
def test_a_damaged_checkpoint_file_is_named(run, tmp_path, name, how):
    folder = _copy(run, tmp_path) / "checkpoints" / "step_300"
    check_checkpoint(folder)
    damage(folder / name, how)
    with pytest.raises(CorruptFileError, match=name) as caught:
        check_checkpoint(folder)
    assert Path(caught.value.path).name == name
    with pytest.warns(CheckpointWarning, match=r"step_300.*resuming from .*step_200"):
        assert intact_checkpoint(folder.parents[1]).name == "step_200"


def test_a_checkpoint_without_manifest_is_checked_by_opening_its_files(run, tmp_path):
    folder = _copy(run, tmp_path) / "checkpoints" / "step_300"
    (folder / "manifest.json").unlink()
    assert not check_manifest(folder)
    check_checkpoint(folder)
    damage(folder / "state.pkl", "truncated")
    with pytest.raises(CorruptFileError, match="state.pkl"):
        check_checkpoint(folder)


@pytest.mark.parametrize("manifest", [True, False], ids=["manifest", "no manifest"])
def test_a_damaged_replay_buffer_is_named(run, tmp_path, manifest):
    """An off-policy checkpoint's replay buffer (here a stand-in pickle added to a PPO one):
    checked by the manifest, or opened when the checkpoint predates manifests."""
    import pickle

    folder = _copy(run, tmp_path) / "checkpoints" / "step_300"
    (folder / "replay_buffer.pkl").write_bytes(pickle.dumps({"observations": np.zeros(64)}))
    write_manifest(folder)
    if not manifest:
        (folder / "manifest.json").unlink()
    check_checkpoint(folder)
    damage(folder / "replay_buffer.pkl", "truncated")
    with pytest.raises(CorruptFileError, match="replay_buffer.pkl"):
        check_checkpoint(folder)


def test_resume_falls_back_to_the_newest_intact_checkpoint(run, tmp_path):
    copy = _copy(run, tmp_path)
    damage(copy / "checkpoints" / "step_300" / "model.zip", "truncated")
    with pytest.warns(CheckpointWarning, match="step_300"):
        resumed = train(run_dir=copy, resume=True, total_timesteps=350)
    assert resumed.summary["resumed_from"] == 200 and resumed.summary["steps"] == 350


def test_load_policy_takes_the_newest_intact_checkpoint(run, tmp_path):
    """A run folder without final/: its newest intact checkpoint, not the latest by name; the
    damaged newer one is named in a warning."""
    import shutil

    copy = _copy(run, tmp_path)
    shutil.rmtree(copy / "final")
    damage(copy / "checkpoints" / "step_300" / "model.zip", "truncated")
    with pytest.warns(CheckpointWarning, match="step_300") as caught:
        policy = load_policy(copy)
    assert "loading" in str(caught[0].message) and "step_200" in str(caught[0].message)
    assert policy.algo == "PPO" and policy.vecnormalize is not None


def test_resume_with_no_intact_checkpoint_is_refused_in_one_line(run, tmp_path):
    copy = _copy(run, tmp_path)
    for folder, how in zip(sorted((copy / "checkpoints").iterdir()), DAMAGE, strict=True):
        damage(folder / "model.zip", how)
    with pytest.raises(CorruptFileError, match="no intact checkpoint"):
        intact_checkpoint(copy)
    args = ["train", "pliant-test/PointReach-v0", "--out", str(copy), "--resume"]
    result = CliRunner().invoke(app, args)
    assert result.exit_code != 0
    assert "no intact checkpoint" in result.output and "a bug in Pliant" not in result.output
    assert "model.zip" in result.output


@pytest.mark.parametrize("how", [*DAMAGE, "text"])
def test_eval_of_a_file_that_is_not_a_model_is_one_line(run, tmp_path, how):
    path = tmp_path / "model.zip"
    path.write_bytes((run / "final" / "model.zip").read_bytes())
    (tmp_path / "meta.json").write_text((run / "final" / "meta.json").read_text())
    if how == "text":
        path.write_text("not a model\n")
    else:
        damage(path, how)
    with pytest.raises(CorruptFileError, match="model.zip"):
        load_policy(path)
    result = CliRunner().invoke(app, ["eval", str(path), "--episodes", "1"])
    assert result.exit_code != 0
    assert "model.zip" in result.output and "a bug in Pliant" not in result.output
    assert len(result.output.strip().splitlines()) == 1, result.output


def test_read_checked_names_the_file_and_what_it_should_be(tmp_path):
    path = tmp_path / "x.json"
    path.write_text("")
    with pytest.raises(CorruptFileError, match=r"x.json: an empty file, not JSON"):
        read_checked(path, lambda p: json.loads(p.read_text()), "JSON")
    path.write_text("{")
    with pytest.raises(CorruptFileError, match=r"x.json: not JSON"):
        read_checked(path, lambda p: json.loads(p.read_text()), "JSON")
    with pytest.raises(FileNotFoundError):
        read_checked(tmp_path / "missing.json", lambda p: json.loads(p.read_text()), "JSON")


def test_a_checkpoint_killed_half_way_is_not_resumed_from(run, tmp_path):
    """A checkpoint is written in a hidden folder renamed when complete: a kill leaves the
    hidden folder, which resume ignores."""
    copy = _copy(run, tmp_path)
    half = copy / "checkpoints" / ".step_400.tmp"
    half.mkdir()
    (half / "model.zip").write_bytes(b"PK")
    with warnings.catch_warnings():
        warnings.simplefilter("error", CheckpointWarning)
        assert intact_checkpoint(copy).name == "step_300"


def test_resume_with_a_damaged_configuration_is_one_line(run, tmp_path):
    copy = _copy(run, tmp_path)
    damage(copy / "config.yaml", "random bytes")
    args = ["train", "pliant-test/PointReach-v0", "--out", str(copy), "--resume"]
    result = CliRunner().invoke(app, args)
    assert result.exit_code != 0
    assert "config.yaml" in result.output and "a bug in Pliant" not in result.output


# The trainer waits 2 s after saying "started" (the signal arrives in that wait, the sleep
# goes on after its handler), so that the run stops near step 300 however loaded the machine.
TRAINER = """
import sys
import time
import torch
from stable_baselines3.common.callbacks import BaseCallback
from pliant.learn import TrainConfig, train

torch.set_num_threads(1)


class Started(BaseCallback):
    def _on_step(self) -> bool:
        if self.num_timesteps == 300:
            print("started", flush=True)
            time.sleep(2.0)
        return True


config = TrainConfig(**__CONFIG__)
result = train(config, sys.argv[1], extra_callbacks=[Started()])
print("stopped_by", result.summary["stopped_by"], result.summary["steps"], flush=True)
"""


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_a_signal_stops_training_at_a_checkpoint_and_resume_is_exact(tmp_path, sig):
    """SIGTERM or SIGINT: the run saves a checkpoint at the next rollout start, exits with
    status 0, and a resume from it ends on the parameters of an uninterrupted run."""
    import torch

    from pliant.learn import parameters

    settings = dict(
        env_id="pliant-test/PointReach-v0",
        algo="PPO",
        total_timesteps=600,
        n_envs=1,
        vec_env="dummy",
        eval_freq=0,
        eval_episodes=0,
        checkpoint_freq=0,
        video_episodes=0,
        normalize=True,
        seed=4,
        hyperparams={"policy": "MlpPolicy", "n_steps": 50, "batch_size": 25},
    )
    code = textwrap.dedent(TRAINER).replace("__CONFIG__", repr(settings))
    cut = tmp_path / "cut"
    child = subprocess.Popen(
        [sys.executable, "-c", code, str(cut)], cwd=ROOT, stdout=subprocess.PIPE, text=True
    )
    try:
        assert child.stdout.readline().strip() == "started"
        os.kill(child.pid, sig)
        out, _ = child.communicate(timeout=120)
    finally:
        if child.poll() is None:
            child.kill()
    assert child.returncode == 0
    assert f"stopped_by {signal.Signals(sig).name}" in out
    stopped_at = int(out.split()[-1])
    checkpoints = [p.name for p in (cut / "checkpoints").iterdir()]
    assert checkpoints and all(int(n[5:]) <= stopped_at for n in checkpoints), checkpoints
    assert not (cut / "final").exists()
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        resumed = train(run_dir=cut, resume=True)
        whole = train(TrainConfig(**settings), tmp_path / "whole")
    finally:
        torch.set_num_threads(threads)
    assert 300 <= resumed.summary["resumed_from"] < 600 and resumed.summary["steps"] == 600
    a, b = parameters(whole.model), parameters(resumed.model)
    for key in a:
        np.testing.assert_array_equal(a[key], b[key], err_msg=key)


def test_a_full_disk_during_a_checkpoint_keeps_the_earlier_ones(run, tmp_path, monkeypatch):
    """The disk fills while the checkpoint at step 400 is written: the run stops with a
    TrainingError naming it, no partial folder is left, and --resume goes on from step 300."""
    import errno

    from pliant.errors import TrainingError
    from pliant.learn import callbacks

    copy = _copy(run, tmp_path)
    real = callbacks.write_manifest

    def full(folder):
        if folder.name == ".step_400.tmp":
            raise OSError(errno.ENOSPC, "No space left on device")
        real(folder)

    monkeypatch.setattr(callbacks, "write_manifest", full)
    with pytest.raises(TrainingError, match=r"step 400: cannot write the checkpoint .*step_400"):
        train(run_dir=copy, resume=True, total_timesteps=500)
    monkeypatch.undo()
    names = sorted(p.name for p in (copy / "checkpoints").iterdir())
    assert names == ["step_100", "step_200", "step_300"]
    resumed = train(run_dir=copy, resume=True, total_timesteps=500)
    assert resumed.summary["resumed_from"] == 300 and resumed.summary["steps"] == 500


@pytest.mark.parametrize("text", ["a: [1,\n", "", "- just\n- a list\n"])
def test_a_training_configuration_that_is_not_yaml_is_one_line(tmp_path, text):
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    args = ["train", "pliant-test/PointReach-v0", "--config", str(path), "--out", str(tmp_path)]
    result = CliRunner().invoke(app, args)
    assert result.exit_code != 0
    assert "bad.yaml" in result.output and "a bug in Pliant" not in result.output
    assert len(result.output.strip().splitlines()) == 1, result.output


@pytest.mark.parametrize("how", DAMAGE)
def test_a_damaged_learning_curve_is_named_on_resume(tmp_path, how):
    from pliant.files import write_json
    from pliant.learn.callbacks import EvalCallback

    curve = EvalCallback(tmp_path, None, 100, 2, None)
    write_json(curve.path, [{"step": 100, "mean_return": -1.0, "success_rate": 0.5}] * 20)
    curve.load_curve(100)
    damage(curve.path, how)
    with pytest.raises(CorruptFileError, match="evaluations.json"):
        curve.load_curve(100)
