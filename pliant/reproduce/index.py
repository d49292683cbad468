"""The thesis-against-ours tables, written from the registry and the committed result files:
``experiments/README.md`` (the index of studies, checked by a test) and the docs' results page
(rendered at build time by ``docs/hooks/results.py``)."""

from __future__ import annotations

from pathlib import Path

from pliant.reproduce.registry import ROOT, FigureError, Study
from pliant.reproduce.studies import STUDIES

README = ROOT / "experiments" / "README.md"

_HEADER = """\
# Experiments: the thesis' results, reproduced

Generated from the results registry (`pliant/reproduce/studies.py`) and the committed result
files by `pliant reproduce --write-index`; `tests/interface/test_reproduce.py` fails when this file
differs from what the registry generates. Ours is read from the result file, never typed in.

- `pliant reproduce --list`: every study, the thesis' value and ours.
- `pliant reproduce NAME`: re-run a study and compare its figures with the committed ones
  (the tolerance is per figure); `--quick`: its quick variant, which checks the pipeline
  still produces its figures; `--check`: the committed figures against the thesis.
- `pliant reproduce NAME --evaluate`: re-evaluate the kept policy or model behind a study's
  figures from the repository alone (where it is kept; the studies table says why not).
- `pliant reproduce --all --quick`: every quick variant (`.ci/reproduce-quick` in CI); the
  times beside them were measured on the shared 2-core machine at load 6-10.
"""


def _cell(text: str) -> str:
    return text.replace("|", "\\|")


def figures_table(studies: tuple[Study, ...] = STUDIES, root: Path = ROOT) -> str:
    """One row a figure: thesis result, study, figure, thesis value, ours (and where it is
    read), whether it meets the thesis' value, the departure from the thesis."""
    lines = [
        "| thesis | study | figure | thesis value | ours | read from | meets the thesis |"
        " departure from the thesis | selection protocol |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    verdicts = {True: "yes", False: "no", None: "-"}
    for study in studies:
        for figure in study.figures:
            try:
                value = figure.read(root)
                ours, verdict = figure.ours_text(value), verdicts[figure.meets_thesis(value)]
            except FigureError:
                ours, verdict = "missing", "-"
            lines.append(
                f"| {study.thesis} | `{study.name}` | {_cell(figure.name)} | "
                f"{figure.thesis_text()} | {ours} | `{figure.file}`: `{figure.path}` | {verdict} |"
                f" {_cell(figure.departure)} | {_cell(figure.protocol)} |"
            )
    return "\n".join(lines) + "\n"


def studies_table(studies: tuple[Study, ...] = STUDIES) -> str:
    """One row a study: its command, result files, quick variant, re-evaluation and report."""
    lines = [
        "| study | thesis | command | result files | quick variant | re-evaluation of the kept"
        " policy or model | report |"
    ]
    lines.append("|---|---|---|---|---|---|---|")
    for study in studies:
        files = "<br>".join(f"`{f}`" for f in dict.fromkeys(g.file for g in study.figures))
        if study.quick is not None:
            quick = f"`{_cell(study.quick.command)}` ({study.quick.seconds:.0f} s)"
        else:
            quick = "none: " + _cell(study.no_quick)
        if study.evaluate is not None:
            kept = f"`{_cell(study.evaluate.command)}` ({study.evaluate.seconds:.0f} s)"
            if study.evaluate.figures:
                kept += f": {_cell(', '.join(study.evaluate.figures))}; others not kept: "
                kept += _cell(study.not_kept)
        else:
            kept = "none: " + _cell(study.not_kept) if study.not_kept else "-"
            if study.retrain:
                kept += f"; re-trained by `{_cell(study.retrain)}`"
        lines.append(
            f"| `{study.name}` | {study.thesis}: {_cell(study.title)} | "
            f"`{_cell(study.command)}` | {files} | {quick} | {kept} | {study.docs} |"
        )
    return "\n".join(lines) + "\n"


def readme(studies: tuple[Study, ...] = STUDIES, root: Path = ROOT) -> str:
    """The text of ``experiments/README.md``."""
    return (
        _HEADER
        + "\n## The thesis' results beside ours\n\n"
        + figures_table(studies, root)
        + "\n## The studies\n\n"
        + studies_table(studies)
    )
