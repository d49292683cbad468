"""Fault injection into the long jobs (issue 22): a worker killed, the parent killed, a chunk
corrupted, the disk full, during `condensed collect` and during training. The job resumes or
fails with a clear message, and nothing already written is lost."""

from __future__ import annotations

import dataclasses
import json
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("torch")
pytest.importorskip("h5py")

import fault_injection  # noqa: E402
import torch  # noqa: E402
from typer.testing import CliRunner  # noqa: E402

from pliant import processes  # noqa: E402
from pliant.cli import app  # noqa: E402
from pliant.condensed import collect as collection  # noqa: E402
from pliant.condensed.collect import CorruptChunkWarning, collect, verify  # noqa: E402
from pliant.condensed.dataset import CollectionPlan, Dataset, Split  # noqa: E402
from pliant.condensed.learned import LearnedCondensedModel  # noqa: E402
from pliant.condensed.networks import StandardisedMLP  # noqa: E402
from pliant.condensed.train import TrainConfig, fit, train_condensed  # noqa: E402
from pliant.errors import DatasetError, LearnedModelError, TrainingError  # noqa: E402
from pliant.processes import driver_identity, exit_with_process  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
# The coarse Finger, cables 0-4 mm: 16 + 4 samples in chunks of 2, a second on one core.
PLAN = CollectionPlan("finger", ((0.0, 4.0), (0.0, 4.0)), 16, chunk_size=2, seed=3)
TRAINING = TrainConfig(epochs=6, batch_size=4, learning_rate=1e-3, hidden=(16,), progress=False)


def _assert_same(a: Dataset, b: Dataset) -> None:
    for name in ("train", "test"):
        for f in dataclasses.fields(Split):
            np.testing.assert_array_equal(
                getattr(a.split(name), f.name), getattr(b.split(name), f.name), err_msg=f.name
            )


@pytest.fixture(scope="module")
def reference(tmp_path_factory) -> Dataset:
    """The dataset of PLAN collected without faults."""
    return collect(PLAN, tmp_path_factory.mktemp("reference") / "finger.h5", workers=1)


def _parts(out: Path) -> Path:
    return out.with_name(out.name + ".parts")


def _start_collection(out: Path, task: str, **env: str) -> subprocess.Popen:
    """`collect(PLAN, out, workers=2)` in a child process whose workers run fault_injection's
    `task` instead of solve_chunk."""
    code = f"""
        import json, sys
        import fault_injection
        from pliant.condensed import collect as collection
        from pliant.condensed.dataset import CollectionPlan
        from pliant.errors import PliantError

        collection.solve_chunk = fault_injection.{task}
        plan = CollectionPlan.from_dict(json.loads({json.dumps(PLAN.to_dict())!r}))
        try:
            collection.collect(plan, {str(out)!r}, workers=2)
        except PliantError as exc:
            print(type(exc).__name__, exc, flush=True)
            sys.exit(3)
    """
    path = os.pathsep.join(
        [str(ROOT), str(Path(__file__).parent), os.environ.get("PYTHONPATH", "")]
    )
    return subprocess.Popen(
        [sys.executable, "-c", textwrap.dedent(code)],
        cwd=ROOT,
        env={**os.environ, "PYTHONPATH": path, **env},
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )


def _children(pid: int) -> list[int]:
    """Live processes whose parent is `pid` (from /proc)."""
    found = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                fields = (entry / "stat").read_text().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if int(fields[1]) == pid and fields[0] != "Z":
                found.append(int(entry.name))
    return found


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"  # a zombie has ended; only its parent's bookkeeping is left


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads /proc")
def test_a_killed_worker_ends_the_collection_with_a_worker_error_and_it_resumes(
    reference, tmp_path
) -> None:
    out = tmp_path / "finger.h5"
    child = _start_collection(out, "dying_solve_chunk", **{fault_injection.DIE_AT_ENV: "6"})
    output, _ = child.communicate(timeout=240)
    assert child.returncode == 3, output
    assert "WorkerError" in output and "rerun the same command" in output
    assert not out.exists()
    saved = sorted(p.name for p in _parts(out).glob("*.npz"))
    assert "train-0000006-0000008.npz" not in saved  # the chunk of the killed worker
    done: list[int] = []
    dataset = collect(PLAN, out, workers=1, on_chunk=lambda d, total: done.append(d))
    assert done[0] == 2 * len(saved) + 2  # the saved chunks were not solved again
    _assert_same(dataset, reference)
    assert not _parts(out).exists()


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads /proc")
def test_workers_exit_when_their_parent_is_killed(tmp_path) -> None:
    child = _start_collection(
        tmp_path / "finger.h5", "slow_solve_chunk", **{fault_injection.SLOW_ENV: "30"}
    )
    workers: list[int] = []
    try:
        deadline = time.monotonic() + 120
        while len(workers) < 2 and time.monotonic() < deadline:  # two workers and a tracker
            time.sleep(0.2)
            workers = [p for p in _children(child.pid) if p != child.pid]
        assert len(workers) >= 2, "the workers did not start"
        time.sleep(1.0)  # let them reach their task
        os.kill(child.pid, signal.SIGKILL)
        child.wait(timeout=30)
        deadline = time.monotonic() + 10  # the watchdog polls twice a second
        while any(_alive(p) for p in workers) and time.monotonic() < deadline:
            time.sleep(0.1)
        assert not any(_alive(p) for p in workers), "orphaned workers are still running"
    finally:
        for pid in workers:  # never leave a stray process behind a failed test
            if _alive(pid):
                os.kill(pid, signal.SIGKILL)
        if child.poll() is None:
            child.kill()


# A Ray cluster that outlives the driver (as `ray start` gives), so that its actors end only
# if the cluster or their own watchdog ends them; SIGTERM shuts it down cleanly.
RAY_CLUSTER = """
import signal, sys, time
import ray
signal.signal(signal.SIGTERM, lambda *_: sys.exit(0))
context = ray.init(address="local", num_cpus=3, include_dashboard=False, log_to_driver=False)
print("ADDRESS", context.address_info["address"], flush=True)
while True:
    time.sleep(1)
"""
# The driver: two environment actors behind RayVecEnv, and one detached actor, which Ray keeps
# after its driver's death by design, so that only the watchdog ends it.
RAY_DRIVER = """
import os, sys, time
from functools import partial
import ray
from pliant.learn.distributed import EnvWorker, RayVecEnv
from pliant.learn.vec import make_env
from pliant.processes import driver_identity

ray.init(address=sys.argv[1], log_to_driver=False)
factory = partial(make_env, "pliant-test/PointReach-v0")
venv = RayVecEnv([factory, factory])
detached = ray.remote(num_cpus=1)(EnvWorker).options(lifetime="detached")
actors = [*venv.workers, detached.remote(factory, driver_identity())]
pids = ray.get([a.__ray_call__.remote(lambda worker: os.getpid()) for a in actors])
print("ACTORS", *pids, flush=True)
while True:
    time.sleep(1)
"""


def _line(process: subprocess.Popen, prefix: str, timeout: float) -> list[str]:
    deadline = time.monotonic() + timeout
    for line in process.stdout:
        if line.startswith(prefix):
            return line.split()[1:]
        assert time.monotonic() < deadline, f"no {prefix} line in {timeout} s"
    raise AssertionError(f"the process ended before printing {prefix}")


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads /proc")
def test_ray_actors_exit_when_their_driver_is_killed() -> None:
    pytest.importorskip("ray", reason="Ray is not installed (optional extra pliant[ray])")
    path = os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])
    # token authentication would have the driver look for the cluster's token on disk
    env = {**os.environ, "PYTHONPATH": path, "RAY_AUTH_MODE": "disabled"}
    run = {"cwd": ROOT, "env": env, "stdout": subprocess.PIPE, "text": True}
    cluster = subprocess.Popen([sys.executable, "-c", RAY_CLUSTER], **run)
    driver, actors = None, []
    try:
        (address,) = _line(cluster, "ADDRESS", 60)
        driver = subprocess.Popen([sys.executable, "-c", RAY_DRIVER, address], **run)
        actors = [int(pid) for pid in _line(driver, "ACTORS", 60)]
        assert len(actors) == 3 and all(_alive(pid) for pid in actors)
        os.kill(driver.pid, signal.SIGKILL)
        driver.wait(timeout=30)
        deadline = time.monotonic() + 5  # the watchdog polls twice a second
        while any(_alive(pid) for pid in actors) and time.monotonic() < deadline:
            time.sleep(0.1)
        assert not [pid for pid in actors if _alive(pid)], "actors outlived their driver"
    finally:
        for pid in actors:  # never leave a stray process behind a failed test
            if _alive(pid):
                os.kill(pid, signal.SIGKILL)
        if driver is not None and driver.poll() is None:
            driver.kill()
        cluster.terminate()
        cluster.wait(timeout=60)


def test_a_dead_ray_environment_worker_stops_the_run_with_a_worker_error() -> None:
    """An environment's Ray actor that dies (here killed) makes the next step a WorkerError
    giving Ray's cause in one line, not a hang nor Ray's own exception."""
    ray = pytest.importorskip("ray", reason="Ray is not installed (optional extra pliant[ray])")
    import gymnasium as gym

    from pliant.errors import WorkerError
    from pliant.learn.distributed import RayVecEnv

    try:
        venv = RayVecEnv([lambda: gym.make("Pendulum-v1")] * 2, address="local")
        venv.reset()
        ray.kill(venv.workers[1])
        with pytest.raises(WorkerError, match="a Ray actor") as caught:
            venv.step(np.zeros((2, 1), np.float32))
        assert "\n" not in str(caught.value)
    finally:
        ray.shutdown()


# A learner whose two environment workers are in a long step (a FEM step under load can take
# seconds): they notice a dead learner only at their next message, unless they watch it.
SLOW_LEARNER = """
import os, time
import gymnasium as gym
import numpy as np
from pliant.learn.vec import RestartingSubprocVecEnv

class Slow(gym.Env):
    observation_space = gym.spaces.Box(-1.0, 1.0, (1,))
    action_space = gym.spaces.Box(-1.0, 1.0, (1,))

    def reset(self, seed=None, options=None):
        return np.zeros(1, np.float32), {}

    def step(self, action):
        time.sleep(120)
        return np.zeros(1, np.float32), 0.0, False, False, {}

venv = RestartingSubprocVecEnv([Slow, Slow])
venv.reset()
venv.step_async(np.zeros((2, 1)))
print("WORKERS", *[p.pid for p in venv.processes], flush=True)
time.sleep(600)
"""


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads /proc")
def test_environment_workers_in_a_long_step_exit_when_their_learner_is_killed() -> None:
    path = os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])
    learner = subprocess.Popen(
        [sys.executable, "-c", SLOW_LEARNER],
        cwd=ROOT,
        env={**os.environ, "PYTHONPATH": path},
        stdout=subprocess.PIPE,
        text=True,
    )
    workers: list[int] = []
    try:
        workers = [int(pid) for pid in _line(learner, "WORKERS", 60)]
        time.sleep(0.5)  # into their step
        os.kill(learner.pid, signal.SIGKILL)
        learner.wait(timeout=30)
        deadline = time.monotonic() + 5  # the watchdog polls twice a second
        while any(_alive(pid) for pid in workers) and time.monotonic() < deadline:
            time.sleep(0.1)
        assert not [pid for pid in workers if _alive(pid)], "workers outlived their learner"
    finally:
        for pid in workers:
            if _alive(pid):
                os.kill(pid, signal.SIGKILL)
        if learner.poll() is None:
            learner.kill()


def test_the_watchdog_tells_its_driver_from_a_process_that_reuses_its_id() -> None:
    ended = subprocess.Popen([sys.executable, "-c", "pass"])
    ended.wait()
    assert not processes.is_running(driver_identity(ended.pid))
    me = driver_identity()
    assert processes.is_running(me)
    if me.start is not None:  # the same pid, started later: another process
        assert not processes.is_running(dataclasses.replace(me, start=me.start + 1))
    # a driver on another machine is left to Ray's own bookkeeping
    assert not exit_with_process(dataclasses.replace(me, machine="another machine"))


def _interrupted(out: Path, chunks: int) -> None:
    """Collect PLAN into `out` and stop it after `chunks` chunks (as a Ctrl-C would)."""
    done: list[int] = []

    def stop(d: int, total: int) -> None:
        done.append(d)
        if len(done) == chunks:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        collect(PLAN, out, workers=1, on_chunk=stop)


def test_a_corrupt_chunk_is_named_by_verify_and_solved_again(reference, tmp_path) -> None:
    out = tmp_path / "finger.h5"
    _interrupted(out, 4)
    chunk = _parts(out) / "train-0000002-0000004.npz"
    data = np.load(chunk)
    arrays = {k: data[k] for k in data.files}
    arrays["w_triangle"][1, 2] += 1e-3  # a bit rot that the zip's own CRC would pass
    np.savez(chunk, **arrays)
    assert verify(out) == [f"the saved chunk {chunk} fails its checksum (corrupt)"]
    result = CliRunner().invoke(app, ["condensed", "verify", str(out)])
    assert result.exit_code == 1 and "train-0000002-0000004.npz" in result.output
    with pytest.warns(CorruptChunkWarning, match="train-0000002"):
        dataset = collect(PLAN, out, workers=1)
    _assert_same(dataset, reference)
    assert verify(out) == []


def test_a_full_disk_during_collection_keeps_the_chunks_saved(
    reference, tmp_path, monkeypatch
) -> None:
    out = tmp_path / "finger.h5"
    real, calls = np.savez, []

    def disk_fills_at_the_fourth_chunk(file, *args, **kwargs):
        calls.append(file)
        if len(calls) >= 4:
            raise OSError(28, "No space left on device")
        return real(file, *args, **kwargs)

    monkeypatch.setattr(collection.np, "savez", disk_fills_at_the_fourth_chunk)
    with pytest.raises(DatasetError, match="No space left on device.*rerun the same command"):
        collect(PLAN, out, workers=1)
    monkeypatch.undo()
    files = sorted(p.name for p in _parts(out).iterdir())
    assert files == ["plan.json", *(f"train-{i:07d}-{i + 2:07d}.npz" for i in (0, 2, 4))]
    _assert_same(collect(PLAN, out, workers=1), reference)


def test_a_full_disk_when_writing_the_dataset_keeps_every_chunk(
    reference, tmp_path, monkeypatch
) -> None:
    out = tmp_path / "finger.h5"

    def full(self, filename):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(Dataset, "_write", full)
    with pytest.raises(DatasetError, match="every chunk is saved"):
        collect(PLAN, out, workers=1)
    monkeypatch.undo()
    assert not out.exists() and len(list(_parts(out).glob("*.npz"))) == 10
    assert not list(tmp_path.glob(".finger.h5*"))  # no temporary file left behind
    _assert_same(collect(PLAN, out, workers=1), reference)


def test_overwrite_replaces_a_finished_or_corrupt_dataset(reference, tmp_path) -> None:
    out = tmp_path / "finger.h5"
    out.write_bytes(b"a corrupt dataset")
    with pytest.raises(DatasetError, match="--overwrite"):
        collect(PLAN, out, workers=1)
    assert verify(out)  # and verify says it is bad
    _assert_same(collect(PLAN, out, workers=1, overwrite=True), reference)
    assert verify(out) == []


def test_a_4kb_random_overwrite_inside_the_dataset_fails_its_checksum(reference, tmp_path) -> None:
    path = reference.save(tmp_path / "copy.h5")
    data = bytearray(path.read_bytes())
    rng = np.random.default_rng(7)
    detected = 0
    for trial in range(5):
        damaged = bytearray(data)
        start = int(rng.integers(0, len(data) - 4096))
        damaged[start : start + 4096] = rng.integers(0, 256, 4096, dtype=np.uint8).tobytes()
        bad = tmp_path / f"bad{trial}.h5"
        bad.write_bytes(bytes(damaged))
        with pytest.raises(DatasetError):
            Dataset.load(bad)
        detected += bool(verify(bad))
    assert detected == 5


@pytest.mark.parametrize(("samples", "fraction"), [(1, 0.25), (2, 0.25), (4, 0.0)])
def test_collections_without_test_samples_finish(samples, fraction, tmp_path) -> None:
    plan = dataclasses.replace(PLAN, n_train=samples, test_fraction=fraction)
    out = tmp_path / "small.h5"
    dataset = collect(plan, out, workers=1)
    assert len(dataset.train) == samples and len(dataset.test) == plan.n_test == 0
    assert Dataset.load(out).test.delta_a.shape == (0, 2)
    assert not _parts(out).exists()


def test_training_without_test_samples_keeps_its_best_training_epoch(tmp_path) -> None:
    plan = dataclasses.replace(PLAN, n_train=4, test_fraction=0.0)
    dataset = collect(plan, tmp_path / "small.h5", workers=1)
    learned, result = train_condensed(dataset, TRAINING)
    losses = [h["train"] for h in result.history]
    assert result.best_epoch == 1 + int(np.argmin(losses)) and result.best_epoch > 0


def test_a_failed_checkpoint_write_keeps_the_last_one_and_training_resumes(
    reference, tmp_path, monkeypatch
) -> None:
    checkpoint = tmp_path / "run.ckpt"
    config = dataclasses.replace(TRAINING, checkpoint=checkpoint, checkpoint_every=2)
    _, uninterrupted = train_condensed(reference, dataclasses.replace(config, checkpoint=None))
    real, calls = torch.save, []

    def disk_fills_at_the_second_checkpoint(obj, f, *args, **kwargs):
        calls.append(f)
        if len(calls) == 2:
            raise RuntimeError("PytorchStreamWriter failed writing file: No space left")
        return real(obj, f, *args, **kwargs)

    monkeypatch.setattr(torch, "save", disk_fills_at_the_second_checkpoint)
    with pytest.raises(TrainingError, match="epoch 4: cannot write the checkpoint"):
        train_condensed(reference, config)
    monkeypatch.undo()
    assert torch.load(checkpoint, weights_only=True)["epoch"] == 2  # the last one, intact
    assert [p.name for p in tmp_path.iterdir()] == ["run.ckpt"]  # no temporary file
    _, resumed = train_condensed(reference, config)
    assert resumed.best_epoch == uninterrupted.best_epoch
    np.testing.assert_allclose(
        [h["train"] for h in resumed.history], [h["train"] for h in uninterrupted.history]
    )


def test_a_non_finite_loss_stops_training_naming_the_epoch(reference) -> None:
    train = reference.train
    x = torch.tensor(train.inputs(), dtype=torch.float32)
    y = torch.tensor(train.outputs(), dtype=torch.float32)
    network = StandardisedMLP(x, y, hidden=(16,))
    y[3, 0] = float("nan")  # a sample the dataset's validation would have refused
    with pytest.raises(TrainingError, match="epoch 1: the training loss is nan"):
        fit(network, (x, y), (x[:0], y[:0]), TRAINING)


def test_models_with_non_finite_weights_are_refused(reference, tmp_path) -> None:
    learned, _ = train_condensed(reference, TRAINING)
    path = learned.save(tmp_path / "model.pt")
    data = torch.load(path, weights_only=True)
    key = next(k for k in data["state"] if k.endswith("weight"))
    data["state"][key][0, 0] = float("nan")
    torch.save(data, path)
    with pytest.raises(LearnedModelError, match="non-finite weights"):
        LearnedCondensedModel.load(path)
    reference.save(tmp_path / "data.h5")
    result = CliRunner().invoke(
        app, ["condensed", "evaluate", str(path), str(tmp_path / "data.h5")]
    )
    assert result.exit_code == 1 and "non-finite weights" in result.output


def test_the_command_line_offers_overwrite_and_verify(tmp_path) -> None:
    out = tmp_path / "finger.h5"
    args = ["condensed", "collect", "finger", "--out", str(out), "--bounds", "0:4"]
    args += ["--samples", "4", "--test-fraction", "0", "--chunk-size", "2", "--workers", "1"]
    runner = CliRunner()
    assert runner.invoke(app, args).exit_code == 0
    again = runner.invoke(app, args)
    assert again.exit_code == 1 and "--overwrite" in again.output
    assert runner.invoke(app, [*args, "--overwrite"]).exit_code == 0
    sound = runner.invoke(app, ["condensed", "verify", str(out)])
    assert sound.exit_code == 0 and "no corrupt part" in sound.output


def test_a_training_killed_mid_run_resumes_from_an_intact_checkpoint(reference, tmp_path) -> None:
    data, checkpoint = tmp_path / "data.h5", tmp_path / "run.ckpt"
    reference.save(data)
    code = f"""
        from pathlib import Path
        from pliant.condensed.dataset import Dataset
        from pliant.condensed.train import TrainConfig, train_condensed

        config = TrainConfig(epochs=10**6, batch_size=4, hidden=(16,), progress=False,
                             checkpoint=Path({str(checkpoint)!r}), checkpoint_every=1)
        train_condensed(Dataset.load({str(data)!r}), config)
    """
    child = subprocess.Popen([sys.executable, "-c", textwrap.dedent(code)], cwd=ROOT)
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline:
            time.sleep(0.2)
            try:
                if torch.load(checkpoint, weights_only=True)["epoch"] >= 3:
                    break
            except (OSError, RuntimeError, EOFError):
                continue  # not written yet
        os.kill(child.pid, signal.SIGKILL)  # mid-epoch, or mid-write
        child.wait(timeout=30)
    finally:
        if child.poll() is None:
            child.kill()
    saved = torch.load(checkpoint, weights_only=True)["epoch"]  # whole, never torn
    assert saved >= 3
    config = dataclasses.replace(TRAINING, epochs=saved + 2, checkpoint=checkpoint)
    _, resumed = train_condensed(reference, config)
    assert [h["epoch"] for h in resumed.history] == list(range(1, saved + 3))
