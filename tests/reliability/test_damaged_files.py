"""Every file Pliant writes and reads back, damaged (issue 64): each reader, given its file
truncated, emptied or overwritten with random bytes, raises an error of ``pliant.errors``
that names the file (never a bare ValueError, zipfile, pickle, h5py, torch or SQLite error);
and a write killed by SIGKILL half-way leaves the previous file whole, for each way Pliant
writes a file (``pliant.files.atomic_path``, ``State.save``, mesh files, HDF5 files replaced
whole, checkpoint folders renamed when complete)."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import textwrap
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("torch")
pytest.importorskip("h5py")

from fault_injection import DAMAGE, damage  # noqa: E402

from pliant import errors  # noqa: E402
from pliant.errors import PliantError  # noqa: E402
from pliant.files import sha256  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]


def _beam():
    from pliant.fem.body import TetBody
    from pliant.fem.material import Corotational
    from pliant.mesh import box_beam
    from pliant.model import Model

    mesh = box_beam(30.0, 10.0, 10.0, 3, 1, 1)
    clamp = np.flatnonzero(mesh.points[:, 0] <= 1e-9)
    return Model(TetBody(mesh, Corotational(100.0, 0.3), density=1e-6, fixed_nodes=clamp))


# ------------------------------------------------------------------ writers and readers
# Each kind: (write an intact file into a folder -> its path, read it back).
def _state(folder: Path) -> Path:
    _beam().rest_state().save(folder / "state.npz")
    return folder / "state.npz"


def _read_state(path: Path):
    from pliant.model import State

    return State.load(path, _beam())


def _mesh(folder: Path) -> Path:
    from pliant.mesh import box_beam
    from pliant.mesh.io import save_mesh

    save_mesh(box_beam(30.0, 10.0, 10.0, 3, 1, 1), folder / "beam.vtu")
    return folder / "beam.vtu"


def _read_mesh(path: Path):
    from pliant.mesh.io import load_mesh

    return load_mesh(path)


def _snapshots(folder: Path) -> Path:
    from pliant.reduction.pipeline import RampedCommands
    from pliant.reduction.snapshots import LoadCase, collect

    model = _beam()
    case = LoadCase("still", RampedCommands([np.zeros(0)], 0.01), 0.02)
    return collect(model, [case], folder / "snapshots.h5", every=1)


def _read_snapshots(path: Path):
    from pliant.reduction import snapshots

    return snapshots.load(path, _beam())


def _reduced(folder: Path) -> Path:
    from pliant.reduction.basis import ReducedBasis
    from pliant.reduction.ecsw import IntegrationDomain, Selection
    from pliant.reduction.reduced import ReducedModel

    rng = np.random.default_rng(0)
    basis = ReducedBasis(rng.random((20, 3)), rng.random((20, 3, 4)), 0, rng.random(6), "mesh")
    domain = IntegrationDomain(Selection(np.arange(5), np.ones(5), 0.01))
    return ReducedModel(basis, domain, {"robot": "beam"}).save(folder / "reduced.npz")


def _read_reduced(path: Path):
    from pliant.reduction.reduced import ReducedModel

    return ReducedModel.load(path)


def _reference(folder: Path) -> Path:
    from pliant.proxy.references import Reference

    rng = np.random.default_rng(1)
    data = Reference(rng.random((30, 4)), rng.random((30, 8, 3)), rng.random((30, 20, 3)), 0.01)
    data.save(folder / "reference.npz")
    return folder / "reference.npz"


def _read_reference(path: Path):
    from pliant.proxy.references import Reference

    return Reference.load(path)


def _pushes(folder: Path) -> Path:
    from pliant.transfer.pushes import Pushes

    rng = np.random.default_rng(2)
    Pushes(rng.random((3, 5, 9)), rng.random((3, 6, 3)), np.array(["a", "b", "c"])).save(
        folder / "pushes.npz"
    )
    return folder / "pushes.npz"


def _read_pushes(path: Path):
    from pliant.transfer.pushes import Pushes

    return Pushes.load(path)


def _calibrate(path: Path):
    from pliant.proxy.calibrate import calibrate

    reference = np.zeros((5, 2, 3))
    return calibrate(
        lambda p: reference + p["a"], reference, {"a": (0.0, 1.0)}, trials=1,
        storage=f"sqlite:///{path}", startup_trials=1,
    )  # fmt: skip


def _study(folder: Path) -> Path:
    pytest.importorskip("optuna")
    _calibrate(folder / "study.db")
    return folder / "study.db"


def _graph_agent(folder: Path) -> Path:
    import gymnasium as gym

    from pliant.learn.graph import FlatSAC, GraphConfig

    space = gym.spaces.Box(-1.0, 1.0, (2,), np.float32)
    learner = FlatSAC(space, space, GraphConfig(hidden=8, buffer_size=10), seed=0)
    learner.save(folder / "agent.pt")
    return folder / "agent.pt"


def _read_graph_agent(path: Path):
    import gymnasium as gym

    from pliant.learn.graph import FlatSAC, GraphConfig

    space = gym.spaces.Box(-1.0, 1.0, (2,), np.float32)
    FlatSAC(space, space, GraphConfig(hidden=8, buffer_size=10), seed=0).load(path)


def _network(folder: Path) -> Path:
    import torch

    from pliant.condensed.learned import FORMAT, FORMAT_VERSION, write_model_file

    data = {"format": FORMAT, "format_version": FORMAT_VERSION, "w": torch.ones(64)}
    return write_model_file(folder / "network.pt", data)


def _read_network(path: Path):
    from pliant.condensed.learned import FORMAT, FORMAT_VERSION, read_model_file

    return read_model_file(path, FORMAT, FORMAT_VERSION, "learned condensed model")


def _dataset(folder: Path) -> Path:
    from pliant import robots
    from pliant.condensed.dataset import CollectionPlan, Dataset, Split
    from pliant.condensed.layout import Layout

    plan = CollectionPlan("finger", ((0.0, 3.0), (0.0, 0.0)), 3)
    layout = Layout.of(robots.build("finger"))
    rng = np.random.default_rng(4)

    def split(n: int) -> Split:
        n *= plan.rows_per_point
        columns = {k: rng.random((n, w)) for k, w in Split.widths(plan, layout).items()}
        return Split(**columns, converged=np.ones(n, dtype=bool))

    return Dataset(plan, layout, split(plan.n_train), split(plan.n_test)).save(
        folder / "dataset.h5"
    )


def _read_dataset(path: Path):
    from pliant.condensed.dataset import Dataset

    return Dataset.load(path)


def _policy(folder: Path, name: str) -> Callable[[], Path]:
    from pliant.learn import TrainConfig, train

    config = TrainConfig(
        env_id="pliant-test/PointReach-v0", algo="PPO", total_timesteps=32, n_envs=1,
        vec_env="dummy", eval_freq=0, eval_episodes=0, checkpoint_freq=0, video_episodes=0,
        normalize=True, seed=1, hyperparams={"policy": "MlpPolicy", "n_steps": 32,
                                             "batch_size": 16, "n_epochs": 1},
    )  # fmt: skip
    train(config, folder / "run")
    return folder / "run" / "final" / name


def _read_policy(path: Path):
    from pliant.learn.evaluate import load_policy

    return load_policy(path.parent)


READERS = {
    "state": (_state, _read_state),
    "mesh": (_mesh, _read_mesh),
    "reduction snapshots": (_snapshots, _read_snapshots),
    "reduced model": (_reduced, _read_reduced),
    "proxy reference": (_reference, _read_reference),
    "proxy pushes": (_pushes, _read_pushes),
    "proxy calibration study": (_study, _calibrate),
    "graph agent": (_graph_agent, _read_graph_agent),
    "condensed network": (_network, _read_network),
    "condensed dataset": (_dataset, _read_dataset),
    "saved policy": (lambda folder: _policy(folder, "model.zip"), _read_policy),
    "VecNormalize statistics": (lambda folder: _policy(folder, "vecnormalize.pkl"), _read_policy),
}
# An empty SQLite file is an empty database: the study starts afresh there.
ACCEPTED = {("proxy calibration study", "empty")}


@pytest.fixture(scope="module")
def intact(tmp_path_factory) -> Callable[[str], Path]:
    """Each kind's intact file, written once (and read back once)."""
    made: dict[str, Path] = {}

    def get(kind: str) -> Path:
        if kind not in made:
            folder = tmp_path_factory.mktemp(kind.replace(" ", "_"))
            write, read = READERS[kind]
            made[kind] = write(folder)
            read(made[kind])  # the intact file reads back
        return made[kind]

    return get


@pytest.mark.parametrize("how", DAMAGE)
@pytest.mark.parametrize("kind", list(READERS))
def test_a_damaged_file_is_a_typed_error_naming_it(kind, how, intact, tmp_path):
    original = intact(kind)
    shutil.copytree(original.parent, tmp_path / "copy")  # with the files beside it
    path = tmp_path / "copy" / original.name
    damage(path, how)
    _, read = READERS[kind]
    if (kind, how) in ACCEPTED:
        read(path)
        return
    with pytest.raises(PliantError) as caught:
        read(path)
    error = caught.value
    assert type(error).__module__ == errors.__name__, type(error)
    assert path.name in str(error), str(error)
    if isinstance(error, errors.CorruptFileError):
        assert Path(error.path).name == path.name


# ------------------------------------------------------------- writes killed half-way
# Each writer mechanism, stopped by SIGKILL while it writes (a hook that prints "writing" and
# sleeps, in place of the last call of the write): the previous file is whole.
WRITERS = {
    "atomic_path": """
        from pliant.files import atomic_path
        with atomic_path(target) as tmp:
            tmp.write_bytes(b"new" * 1000)
            stop()
    """,
    "State.save": """
        import numpy as np
        np.savez = lambda file, **arrays: (file.write(b"new" * 1000), stop())
        from pliant.model import State
        State(np.zeros((4, 3)), np.zeros((4, 3))).save(target)
    """,
    "save_mesh": """
        import meshio
        from pliant.mesh import box_beam
        from pliant.mesh.io import save_mesh
        meshio.write = lambda name, mesh: (open(name, "wb").write(b"new" * 1000), stop())
        save_mesh(box_beam(30.0, 10.0, 10.0, 3, 1, 1), target)
    """,
    "HDF5 file replaced whole": """
        import numpy as np
        import pliant.reduction.snapshots as snapshots
        from pliant.model import State
        snapshots._finish = lambda group, state, steps: stop()
        state = State(np.zeros((4, 3)), np.zeros((4, 3)))
        case = (np.zeros(1), np.zeros((1, 4, 3)), state, 1)
        snapshots._write_cases(target, {"dt": 0.01}, {"case": case})
    """,
}


@pytest.mark.parametrize("writer", list(WRITERS))
def test_a_write_killed_half_way_leaves_the_previous_file_whole(writer, tmp_path):
    suffix = {"save_mesh": ".vtu", "HDF5 file replaced whole": ".h5"}.get(writer, ".npz")
    target = tmp_path / f"saved{suffix}"
    if suffix == ".h5":  # a snapshot file with no case yet: the writer copies it first
        import h5py

        with h5py.File(target, "w") as f:
            f.attrs["dt"] = 0.01
            f.create_group("cases")
    else:
        target.write_bytes(b"old" * 1000)
    before = sha256(target)
    script = "import sys, time\nfrom pathlib import Path\ntarget = Path(sys.argv[1])\n"
    script += "def stop():\n    print('writing', flush=True)\n    time.sleep(60)\n"
    script += textwrap.dedent(WRITERS[writer])
    child = subprocess.Popen(
        [sys.executable, "-c", script, str(target)], cwd=ROOT, stdout=subprocess.PIPE, text=True
    )
    try:
        assert child.stdout.readline().strip() == "writing"
        os.kill(child.pid, signal.SIGKILL)
        child.wait(timeout=30)
    finally:
        if child.poll() is None:
            child.kill()
    assert child.returncode == -signal.SIGKILL
    assert sha256(target) == before
    # Whatever was half-written is hidden beside it and never read.
    assert [p.name for p in tmp_path.iterdir() if not p.name.startswith(".")] == [target.name]
