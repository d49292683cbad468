"""Running a study and comparing what it produces.

- ``rerun``: the study's command, which rewrites its committed result files; each figure's new
  value is compared with the committed one (read before the run) within the figure's tolerance.
- ``quick``: the quick variant in a fresh folder; each figure of the files it maps must be
  read from what it wrote (a number where the committed file has one): the pipeline still
  produces its figures. Its values are not compared, the run being smaller.
- ``evaluate``: the kept policy or model re-evaluated in a fresh folder; each figure it makes
  (those of the files it maps, or the ones it names) is compared with the committed one within
  the figure's tolerance.
- ``check``: the committed files against the thesis: every figure read, and any that does not
  meet the thesis' value (or is in other units) states its departure.
"""

from __future__ import annotations

import math
import os
import subprocess
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

from pliant.reproduce.registry import ROOT, Figure, FigureError, Study


class StudyFailed(RuntimeError):
    """A study's command exited with an error."""


class NotKept(ValueError):
    """A study's figures cannot be re-evaluated from the repository: in one line, why and the
    command that re-makes what it would need."""


def _not_kept(study: Study) -> str:
    if study.not_kept:
        return (
            f"{study.name} cannot be re-evaluated from the repository: {study.not_kept};"
            f" re-train with `{study.retraining()}`"
        )
    return (
        f"{study.name} keeps no policy or model to re-evaluate: its figures are re-made by"
        f" `pliant reproduce {study.name}` (`{study.command}`)"
    )


@dataclass(frozen=True)
class Row:
    """One figure's outcome: its value(s) and whether it passes, with why not."""

    study: str
    figure: Figure
    ours: float | None
    reference: float | None
    ok: bool
    why: str = ""


def _shell(command: str, root: Path) -> float:
    # A script run by path puts its own folder first on sys.path, not the root: PYTHONPATH makes
    # it import this checkout's pliant rather than another installed one.
    path = os.pathsep.join(filter(None, [str(root), os.environ.get("PYTHONPATH")]))
    start = time.perf_counter()
    result = subprocess.run(
        ["bash", "-c", command], cwd=root, env={**os.environ, "PYTHONPATH": path}
    )
    if result.returncode != 0:
        raise StudyFailed(f"{command!r} exited with {result.returncode}")
    return time.perf_counter() - start


def _compared(
    study: Study, figure: Figure, before: float, root: Path, file: Path | None = None
) -> Row:
    """The figure read again (from `file`, default its committed file) against `before`."""
    try:
        after = figure.read(root, file)
    except FigureError as error:
        return Row(study.name, figure, None, before, False, str(error))
    ok = math.isclose(after, before, rel_tol=figure.tolerance, abs_tol=1e-12)
    why = "" if ok else f"differs by more than {figure.tolerance:.0%} from the committed"
    return Row(study.name, figure, after, before, ok, why)


def rerun(study: Study, root: Path = ROOT) -> tuple[list[Row], float]:
    """Run the study's command; compare each figure with the committed value."""
    committed = {figure: figure.read(root) for figure in study.figures}
    seconds = _shell(study.command, root)
    return [_compared(study, f, before, root) for f, before in committed.items()], seconds


def quick(study: Study, root: Path = ROOT) -> tuple[list[Row], float]:
    """Run the quick variant in a fresh folder; check it wrote every figure of its files."""
    if study.quick is None:
        raise ValueError(f"study {study.name} has no quick variant: {study.no_quick}")
    with tempfile.TemporaryDirectory(prefix=f"pliant-{study.name}-") as out:
        seconds = _shell(study.quick.command.replace("{out}", out), root)
        rows = []
        for figure in study.figures:
            if not study.quick.makes(figure):
                continue
            produced = Path(out) / study.quick.files[figure.file]
            try:
                rows.append(Row(study.name, figure, figure.read(root, produced), None, True))
            except FigureError as error:
                rows.append(Row(study.name, figure, None, None, False, str(error)))
    return rows, seconds


def evaluate(study: Study, root: Path = ROOT) -> tuple[list[Row], float]:
    """Re-evaluate the kept policy or model in a fresh folder; compare with the committed."""
    if study.evaluate is None:
        raise NotKept(_not_kept(study))
    with tempfile.TemporaryDirectory(prefix=f"pliant-{study.name}-") as out:
        seconds = _shell(study.evaluate.command.replace("{out}", out), root)
        rows = [
            _compared(study, f, f.read(root), root, Path(out) / study.evaluate.files[f.file])
            for f in study.figures
            if study.evaluate.makes(f)
        ]
    return rows, seconds


def check(study: Study, root: Path = ROOT) -> list[Row]:
    """Read each committed figure and set it beside the thesis' value."""
    rows = []
    for figure in study.figures:
        try:
            ours = figure.read(root)
        except FigureError as error:
            rows.append(Row(study.name, figure, None, figure.thesis, False, str(error)))
            continue
        meets = figure.meets_thesis(ours)
        if meets or figure.departure or figure.thesis is None:
            why = "" if meets or figure.thesis is None else "departs: " + figure.departure
            rows.append(Row(study.name, figure, ours, figure.thesis, True, why))
        else:
            why = "does not meet the thesis' value and states no departure"
            rows.append(Row(study.name, figure, ours, figure.thesis, False, why))
    return rows
