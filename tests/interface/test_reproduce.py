"""The results registry: every study's figures are read from committed files, the docs quote
what the files hold, experiments/README.md is what the registry generates, and the runner
compares re-runs and quick runs as it says."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest
from typer.testing import CliRunner

from pliant.cli import app
from pliant.reproduce import STUDIES, Figure, FigureError, Quick, Study, index, runner, study
from pliant.reproduce.registry import ROOT

FIGURES = [pytest.param(s, f, id=f"{s.name}:{f.name}") for s in STUDIES for f in s.figures]


def _tracked() -> set[str] | None:
    if not (ROOT / ".git").exists():
        return None
    listing = subprocess.run(
        ["git", "ls-files", "experiments"], cwd=ROOT, capture_output=True, text=True, check=True
    )
    return set(listing.stdout.split())


def test_registry_is_consistent():
    names = [s.name for s in STUDIES]
    assert len(names) == len(set(names))
    for entry in STUDIES:
        assert entry.figures, entry.name
        assert (ROOT / entry.docs).is_file(), entry.docs
        assert (entry.quick is None) != (not entry.no_quick)
        if entry.quick is not None:
            assert "{out}" in entry.quick.command, entry.name
            assert set(entry.quick.files) <= {f.file for f in entry.figures}, entry.name
            assert entry.quick.seconds > 0.0, f"{entry.name}: quick variant not timed"
        for figure in entry.figures:
            assert figure.tolerance >= 0.0
            assert figure.better in ("lower", "higher", "closer")
    assert study("table-3.1").thesis == "Table 3.1"
    with pytest.raises(KeyError, match="no study"):
        study("table-9.9")


def test_commands_name_scripts_that_exist():
    for entry in STUDIES:
        commands = entry.command + ("" if entry.quick is None else " " + entry.quick.command)
        for script in re.findall(r"\S+\.py\b", commands):
            assert (ROOT / script).is_file(), f"{entry.name}: no {script}"


def test_every_reproduced_thesis_result_has_a_study():
    covered = " ".join(s.thesis for s in STUDIES)
    for result in (
        "Table 3.1",
        "Table 3.2",
        "Table 4.1",
        "Table 5.1",
        "Table 5.2",
        "Table 5.8",
        "§3.2.2",
        "§3.3.2",
        "§4.1.3",
        "§4.2.3",
        "§5.2.3",
    ):
        assert result in covered, result


@pytest.mark.parametrize(("entry", "figure"), FIGURES)
def test_figure_is_read_from_a_committed_file(entry, figure):
    tracked = _tracked()
    if tracked is not None:
        assert figure.file in tracked, f"{figure.file} is not tracked: a clone lacks it"
    value = figure.read()
    assert isinstance(value, float)


@pytest.mark.parametrize(("entry", "figure"), FIGURES)
def test_docs_quote_what_the_file_holds(entry, figure):
    """A docs page that reports a registry figure writes the value its file holds."""
    if figure.docs is None:
        pytest.skip("no docs page quotes this figure")
    quote = figure.format(figure.read())
    text = (ROOT / figure.docs).read_text()
    assert re.search(rf"(?<![\d.]){re.escape(quote)}(?!\d)", text), (
        f"{figure.docs} does not say {quote} ({figure.file}:{figure.path})"
    )


def test_committed_figures_meet_the_thesis_or_state_their_departure():
    rows = [row for entry in STUDIES for row in runner.check(entry)]
    assert [row.why for row in rows if not row.ok] == []


def test_experiments_readme_is_generated_from_the_registry():
    assert index.README.read_text() == index.readme(), (
        "experiments/README.md differs from the registry: run `pliant reproduce --write-index`"
    )


def test_list_shows_every_study_with_ours(monkeypatch):
    from pliant.cli.reproduce import console

    # The console's width is fixed when it is made if COLUMNS is set then (pytest-xdist's
    # workers set it to 80): the table must be wide enough not to wrap the studies' names.
    monkeypatch.setattr(console, "_width", 300)
    result = CliRunner().invoke(app, ["reproduce", "--list"])
    assert result.exit_code == 0, result.output
    for entry in STUDIES:
        assert entry.name in result.output
    ours = study("trunk-debris").figures[0]
    assert ours.ours_text(ours.read()) in result.output


def test_check_and_bad_arguments_through_the_cli(monkeypatch):
    monkeypatch.setenv("COLUMNS", "300")
    assert CliRunner().invoke(app, ["reproduce", "table-3.1", "--check"]).exit_code == 0
    for args in (["reproduce"], ["reproduce", "--all"], ["reproduce", "table-9.9", "--check"]):
        result = CliRunner().invoke(app, args)
        lines = [line for line in result.output.splitlines() if line.strip()]
        assert result.exit_code == 2 and len(lines) == 1, result.output
        assert lines[0].startswith("error: ")


# The reading of paths and the runner, on a small made-up study.


def _figure(**changes) -> Figure:
    settings = dict(
        name="distance",
        file="result.json",
        path="runs/*/mm",
        thesis=2.0,
        unit="mm",
        better="lower",
        tolerance=0.1,
    )
    return Figure(**(settings | changes))


def test_paths_walk_keys_indices_fields_and_stars(tmp_path):
    rows = [{"id": "x", "v": 0.25}, {"id": "y", "v": 1.0}, {"id": "y", "v": 2.0}]
    data = {"runs": {"a": {"mm": 1.0}, "b": {"mm": 3.0}}, "rows": rows}
    (tmp_path / "result.json").write_text(json.dumps(data))
    assert _figure().read(tmp_path) == 2.0  # the mean of both runs
    assert _figure(path="rows/0/v", scale=100.0).read(tmp_path) == 25.0
    assert _figure(path="rows/id=x/v").read(tmp_path) == 0.25
    assert _figure(path="rows/id=y/v").read(tmp_path) == 1.5  # the mean of a level's draws
    with pytest.raises(FigureError, match="no entry"):
        _figure(path="rows/id=z/v").read(tmp_path)
    with pytest.raises(FigureError, match="has no"):
        _figure(path="runs/c/mm").read(tmp_path)
    with pytest.raises(FigureError, match="not numbers"):
        _figure(path="rows/id=x/id").read(tmp_path)
    with pytest.raises(FigureError, match="no result file"):
        _figure(file="absent.json").read(tmp_path)


def test_meeting_the_thesis():
    assert _figure().meets_thesis(1.5)
    assert not _figure().meets_thesis(2.5)
    assert _figure(better="higher").meets_thesis(2.5)
    assert _figure(better="closer").meets_thesis(2.1)
    assert not _figure(better="closer").meets_thesis(2.5)
    assert _figure(thesis_unit="cm", departure="other units").meets_thesis(1.0) is None
    assert _figure(fmt="{:.2e}").format(4.78e-7) == "4.78e-7"
    assert _figure(fmt="{:,.0f}").format(40000.2) == "40 000"
    with pytest.raises(ValueError, match="departure"):
        Study("s", "T", "t", "true", (_figure(thesis_unit="cm"),), no_quick="none")
    with pytest.raises(ValueError, match="quick variant"):
        Study("s", "T", "t", "true", (_figure(),))


WRITER = (
    "import json, sys; "
    "json.dump({'runs': {'a': {'mm': float(sys.argv[1])}}}, open(sys.argv[2], 'w'))"
)


def _writer(value: float, target: str) -> str:
    """A study's command: write ``value`` as the run's figure into ``target``."""
    return f'{sys.executable} -c "{WRITER}" {value} {target}'


def test_rerun_compares_with_the_committed_figures(tmp_path):
    (tmp_path / "result.json").write_text(json.dumps({"runs": {"a": {"mm": 1.0}}}))
    close = Study("s", "T", "t", _writer(1.05, "result.json"), (_figure(),), no_quick="none")
    rows, _ = runner.rerun(close, tmp_path)
    assert [(row.ok, row.reference, row.ours) for row in rows] == [(True, 1.0, 1.05)]
    far = Study("s", "T", "t", _writer(2.0, "result.json"), (_figure(),), no_quick="none")
    assert not runner.rerun(far, tmp_path)[0][0].ok
    failing = Study("s", "T", "t", "exit 3", (_figure(),), no_quick="none")
    with pytest.raises(runner.StudyFailed, match="exited with 3"):
        runner.rerun(failing, tmp_path)


def test_quick_variant_must_produce_its_figures(tmp_path):
    produces = Quick(_writer(7.0, "{out}/small.json"), {"result.json": "small.json"}, 1.0)
    rows, _ = runner.quick(Study("s", "T", "t", "true", (_figure(),), quick=produces), tmp_path)
    assert [(row.ok, row.ours) for row in rows] == [(True, 7.0)]
    silent = Quick("true", {"result.json": "small.json"}, 1.0)
    rows, _ = runner.quick(Study("s", "T", "t", "true", (_figure(),), quick=silent), tmp_path)
    assert not rows[0].ok
    # a quick run too short to reach a figure names the ones it makes: only those are checked
    other = _figure(name="not reached")
    named = Quick("true", {"result.json": "small.json"}, 1.0, figures=("not made",))
    rows, _ = runner.quick(Study("s", "T", "t", "true", (other,), quick=named), tmp_path)
    assert rows == []
    named = Quick(produces.command, produces.files, 1.0, figures=("not reached",))
    rows, _ = runner.quick(Study("s", "T", "t", "true", (other,), quick=named), tmp_path)
    assert [(row.ok, row.ours) for row in rows] == [(True, 7.0)]


def test_a_figure_path_outside_the_repository_is_refused():
    assert all(
        not Path(f.file).is_absolute() and ".." not in f.file for s in STUDIES for f in s.figures
    )


def test_docs_results_page_is_filled_from_the_registry():
    from pliant.reproduce.docs_hook import MARKERS, on_page_markdown

    page = (ROOT / "docs" / "results.md").read_text()
    assert all(marker in page for marker in MARKERS)
    rendered = on_page_markdown(page, page=None)
    assert not any(marker in rendered for marker in MARKERS)
    for entry in STUDIES:
        assert f"`{entry.name}`" in rendered
        for figure in entry.figures:
            assert figure.ours_text(figure.read()) in rendered


def test_evaluation_of_the_kept_model_compares_with_the_committed(tmp_path):
    (tmp_path / "result.json").write_text(json.dumps({"runs": {"a": {"mm": 1.0}}}))
    kept = Quick(_writer(1.02, "{out}/again.json"), {"result.json": "again.json"}, 1.0)
    entry = Study("s", "T", "t", "true", (_figure(),), no_quick="none", evaluate=kept)
    rows, _ = runner.evaluate(entry, tmp_path)
    assert [(row.ok, row.reference, row.ours) for row in rows] == [(True, 1.0, 1.02)]
    drifted = Quick(_writer(3.0, "{out}/again.json"), {"result.json": "again.json"}, 1.0)
    entry = Study("s", "T", "t", "true", (_figure(),), no_quick="none", evaluate=drifted)
    assert not runner.evaluate(entry, tmp_path)[0][0].ok
    lost = Study("s", "T", "t", "true", (_figure(),), no_quick="none", not_kept="runs/ ignored")
    with pytest.raises(ValueError, match="runs/ ignored"):
        runner.evaluate(lost, tmp_path)
    with pytest.raises(ValueError, match="no kept model"):
        Study("s", "T", "t", "true", (_figure(),), no_quick="none", evaluate=kept, not_kept="x")


def test_a_re_evaluation_of_some_figures_compares_those_and_says_why_not_the_others(tmp_path):
    """Where only some figures' models are kept, the re-evaluation names its figures; the
    others are left out of the comparison and the study says why they are not kept."""
    (tmp_path / "result.json").write_text(json.dumps({"runs": {"a": {"mm": 1.0}}}))
    figures = (_figure(), _figure(name="other", path="runs/a/mm"))
    some = Quick(
        _writer(1.02, "{out}/again.json"), {"result.json": "again.json"}, 1.0, ("distance",)
    )
    entry = Study("s", "T", "t", "true", figures, no_quick="none", evaluate=some, not_kept="big")
    rows, _ = runner.evaluate(entry, tmp_path)
    assert [(row.figure.name, row.ok) for row in rows] == [("distance", True)]
    with pytest.raises(ValueError, match="not why"):
        Study("s", "T", "t", "true", figures, no_quick="none", evaluate=some)
    unknown = Quick("true", {"result.json": "again.json"}, 1.0, ("speed",))
    with pytest.raises(ValueError, match="speed"):
        Study("s", "T", "t", "true", figures, no_quick="none", evaluate=unknown, not_kept="big")


def test_the_kept_models_are_tracked_and_small():
    """A study that re-evaluates its kept policy or model reads it from tracked files only."""
    tracked = _tracked()
    for entry in STUDIES:
        if entry.evaluate is None:
            continue
        assert "{out}" in entry.evaluate.command, entry.name
        assert set(entry.evaluate.files) <= {f.file for f in entry.figures}, entry.name
        for path in re.findall(r"experiments/\S+", entry.evaluate.command.replace('"', " ")):
            folder = ROOT / path
            assert folder.exists(), f"{entry.name}: no {path}"
            files = [folder] if folder.is_file() else [p for p in folder.iterdir() if p.is_file()]
            if tracked is not None:
                assert any(str(p.relative_to(ROOT)) in tracked for p in files), path
            # each kept policy or network small (a condensed network of 3 x 450 is 1.7 MB, three
            # of them Table 5.1's); all tracked results within 30 MB (test_result_files)
            assert all(p.stat().st_size < 3e6 for p in files), f"{path} holds a large file"
            assert sum(p.stat().st_size for p in files) < 6e6, f"{path} is not small"


def test_evaluate_without_a_kept_model_says_so_in_one_line(monkeypatch):
    """A study whose model is not kept answers --evaluate with one line naming the command that
    re-trains it (exit 1: nothing to re-evaluate, no usage error); every study not keeping its
    model says why."""
    monkeypatch.setenv("COLUMNS", "300")
    for entry in STUDIES:
        if entry.evaluate is not None:
            continue
        result = CliRunner().invoke(app, ["reproduce", entry.name, "--evaluate"])
        lines = [line for line in result.output.splitlines() if line.strip()]
        assert result.exit_code == 1 and len(lines) == 1, result.output
        assert lines[0].startswith(f"error: {entry.name} ")
        command = entry.retraining() if entry.not_kept else entry.command
        assert f"`{' '.join(command.split())}`" in lines[0]
    with pytest.raises(ValueError, match="nothing not kept"):
        Study("s", "T", "t", "true", (_figure(),), no_quick="none", retrain="python train.py")


@pytest.mark.slow
def test_the_kept_selector_gives_its_committed_accuracy():
    """The Selector network kept in the repository, re-tested (about 30 s): its figure again."""
    rows, _ = runner.evaluate(study("graph-selector"))
    assert rows and all(row.ok for row in rows), [(row.ours, row.why) for row in rows]


@pytest.mark.slow
def test_the_kept_coarse_finger_gives_its_committed_test_loss():
    """The coarse Finger's condensed network kept in the repository, its test samples solved
    again by the FEM (about 2 min): the committed test loss (its loop rate, a timing of the
    machine, is not asserted here)."""
    rows, _ = runner.evaluate(study("table-5.2"))
    losses = [row for row in rows if row.figure.name == "test loss, coarse mesh"]
    assert losses and all(row.ok for row in losses), [(row.ours, row.why) for row in losses]
