"""No path of the command line calls a file or a scene that is merely bad "a bug in Pliant"
(issue 64): every command that reads a file, given one that is empty, random bytes or of
another kind (and a scene whose script fails), answers in one line ``error: ...`` naming the
file, with exit status 1 or 2."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("torch")

from typer.testing import CliRunner  # noqa: E402

from pliant.cli import app  # noqa: E402

runner = CliRunner()

# {bad}: the bad file (a name with the suffix the command expects); {out}: a fresh folder.
COMMANDS = {
    "run scene .scn": (".scn", ["run", "{bad}", "--out", "{out}", "--duration", "0.01"]),
    "run scene .py": (".py", ["run", "{bad}", "--out", "{out}", "--duration", "0.01"]),
    "inverse scene .py": (".py", ["inverse", "{bad}", "--out", "{out}"]),
    "view saved states": (".npz", ["view", "{bad}", "--robot", "finger"]),
    "eval a model": (".zip", ["eval", "{bad}", "--algo", "PPO", "--episodes", "1"]),
    "enjoy a model": (".zip", ["enjoy", "{bad}", "--algo", "PPO"]),
    "train --config": (
        ".yaml",
        ["train", "pliant-test/PointReach-v0", "--config", "{bad}", "--out", "{out}"],
    ),
    "condensed train": (".h5", ["condensed", "train", "{bad}", "--out", "{out}/m.pt"]),
    "condensed verify": (".h5", ["condensed", "verify", "{bad}"]),
    "condensed evaluate": (".pt", ["condensed", "evaluate", "{bad}", "{bad}"]),
    "condensed control": (".pt", ["condensed", "control", "{bad}"]),
    "condensed design": (".pt", ["condensed", "design", "{bad}", "--out", "{out}"]),
    "trajopt learned model": (".pt", ["trajopt", "finger-mpc-learned", "--model", "{bad}"]),
    "proxy calibrate --reference": (
        ".npz",
        ["proxy", "calibrate", "multigait", "--reference", "{bad}", "--out", "{out}"],
    ),
    "proxy calibrate --start": (
        ".json",
        ["proxy", "calibrate", "multigait", "--start", "{bad}", "--out", "{out}"],
    ),
    "graph train --config": (".json", ["graph", "train", "Corridor", "--config", "{bad}"]),
    "tune --config": (
        ".yaml",
        ["tune", "pliant-test/PointReach-v0", "--config", "{bad}", "--out", "{out}"],
    ),
}

# Files Pliant keeps in an output folder and reads back when the command is run again.
IN_OUTPUT = {
    "reduce: snapshots": ("finger/snapshots.h5", ["reduce", "finger", "--out", "{out}"]),
    "proxy calibrate: study": (
        "multigait.db",
        ["proxy", "calibrate", "multigait", "--reference", "{reference}", "--out", "{out}"],
    ),
    "graph train: checkpoint": (
        "checkpoint.pt",
        ["graph", "train", "Corridor", "--steps", "1", "--out", "{out}"],
    ),
    "train --resume: configuration": (
        "config.yaml",
        ["train", "pliant-test/PointReach-v0", "--out", "{out}", "--resume"],
    ),
}

CONTENTS = {
    "empty": b"",
    "random bytes": np.random.default_rng(0).bytes(2048),
    "text": b"not what the command wants\n",
}
# CI runs the random bytes; the other contents, as slow tests, in the full suite.
CASES = [
    pytest.param(content, marks=() if content == "random bytes" else pytest.mark.slow)
    for content in CONTENTS
]


def _one_line(result, bad: Path) -> None:
    """One line `error: ...` naming the file, the last (a run that resumes prints its settings
    before it reads its files)."""
    lines = [line for line in result.output.splitlines() if line.strip()]
    errors = [line for line in lines if line.startswith("error: ")]
    assert result.exit_code in (1, 2), result.output
    assert "a bug in Pliant" not in result.output, result.output
    assert "Traceback" not in result.output
    assert len(errors) == 1 and lines[-1] == errors[0], result.output
    assert bad.name in result.output.replace("\n", ""), result.output


@pytest.mark.parametrize("content", CASES)
@pytest.mark.parametrize("command", list(COMMANDS))
def test_a_bad_file_given_to_a_command_is_one_line(command, content, tmp_path):
    suffix, args = COMMANDS[command]
    bad = tmp_path / f"bad{suffix}"
    bad.write_bytes(CONTENTS[content])
    args = [a.format(bad=bad, out=tmp_path / "out") for a in args]
    _one_line(runner.invoke(app, args), bad)


@pytest.fixture(scope="module")
def reference(tmp_path_factory) -> Path:
    """A valid reference for the Multigait's proxy (3 steps): the command reaches its study."""
    from pliant.proxy.references import Reference

    surface = np.array([[0.0, 29.0, 0.0], [136.0, -29.0, 0.0], [68.0, 0.0, 0.0]])
    path = tmp_path_factory.mktemp("reference") / "reference.npz"
    Reference(np.zeros((5, 5)), np.zeros((5, 3, 3)), surface, 0.01).save(path)
    return path


@pytest.mark.parametrize("content", CASES[1:])
@pytest.mark.parametrize("command", list(IN_OUTPUT))
def test_a_damaged_file_of_an_earlier_run_is_one_line(command, content, reference, tmp_path):
    name, args = IN_OUTPUT[command]
    out = tmp_path / "out"
    bad = out / name
    bad.parent.mkdir(parents=True)
    bad.write_bytes(CONTENTS[content])
    if command.startswith("train"):  # a run folder with a checkpoint to resume from
        (out / "checkpoints" / "step_10").mkdir(parents=True)
    args = [a.format(out=out, reference=reference) for a in args]
    _one_line(runner.invoke(app, args), bad)


SCENES = {
    "raises": "def createScene(root):\n    raise RuntimeError('the scene is broken')\n",
    "syntax error": "def createScene(root)\n    pass\n",
    "no createScene": "x = 1\n",
    "imports nothing there": "import no_such_module\n\ndef createScene(root):\n    pass\n",
}


@pytest.mark.parametrize("scene", list(SCENES))
def test_a_scene_script_that_fails_is_its_error_not_a_bug(scene, tmp_path):
    bad = tmp_path / "scene.py"
    bad.write_text(SCENES[scene])
    result = runner.invoke(app, ["run", str(bad), "--out", str(tmp_path / "out")])
    _one_line(result, bad)


def test_a_missing_optional_dependency_is_one_line_not_a_bug(tmp_path, monkeypatch):
    """`pliant tune` (and Ray workers) without Ray installed: MissingDependencyError, one line
    saying how to install it."""
    from pliant.errors import MissingDependencyError
    from pliant.processes import run_jobs

    monkeypatch.setitem(sys.modules, "ray", None)  # `import ray` raises ImportError
    sweep = tmp_path / "sweep.yaml"
    sweep.write_text("algo: PPO\nsearch:\n  seed: {grid: [1]}\n")
    args = ["tune", "pliant-test/PointReach-v0", "--config", str(sweep), "--out", str(tmp_path)]
    result = runner.invoke(app, args)
    assert result.exit_code == 1, result.output
    assert result.output.startswith("error: Ray is not installed: pip install 'pliant[ray]'")
    assert "a bug in Pliant" not in result.output and len(result.output.splitlines()) == 1
    with pytest.raises(MissingDependencyError, match=r"pip install 'pliant\[ray\]'"):
        list(run_jobs(abs, [(0, (-1,))], ray_address="local"))
