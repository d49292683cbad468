"""``pliant reproduce``: list the studies, re-run one, run the quick variants, check the
committed figures against the thesis, write experiments/README.md."""

from __future__ import annotations

from typing import Annotated

import typer
from rich.console import Console
from rich.table import Table

from pliant.cli.support import RUNTIME_EXIT, report
from pliant.reproduce import index, runner
from pliant.reproduce.registry import FigureError
from pliant.reproduce.studies import STUDIES, study

console = Console()


def _rows_table(title: str, rows: list[runner.Row], reference: str) -> Table:
    table = Table(title=title)
    for column in ("study", "figure", reference, "ours", "", "note"):
        table.add_column(column)
    for row in rows:
        figure = row.figure
        table.add_row(
            row.study,
            figure.name,
            "-" if row.reference is None else figure.format(row.reference),
            "-" if row.ours is None else figure.ours_text(row.ours),
            "ok" if row.ok else "FAIL",
            row.why,
        )
    return table


def _list() -> None:
    table = Table(title="studies (ours read from the committed result files)")
    for column in ("study", "thesis", "figure", "thesis value", "ours", "quick"):
        table.add_column(column)
    for entry in STUDIES:
        quick = "-" if entry.quick is None else f"{entry.quick.seconds:.0f} s"
        for k, figure in enumerate(entry.figures):
            try:
                ours = figure.ours_text(figure.read())
            except FigureError:
                ours = "missing"
            first = k == 0
            table.add_row(
                entry.name if first else "",
                entry.thesis if first else "",
                figure.name,
                figure.thesis_text(),
                ours,
                quick if first else "",
            )
    console.print(table)


def reproduce_command(
    name: Annotated[str | None, typer.Argument(help="the study to run (see --list)")] = None,
    list_: Annotated[
        bool, typer.Option("--list", help="every study: thesis value and ours")
    ] = False,
    quick: Annotated[
        bool, typer.Option("--quick", help="the quick variant: does it still produce its figures")
    ] = False,
    all_: Annotated[bool, typer.Option("--all", help="every study (with --quick or --check)")] = (
        False
    ),
    check: Annotated[
        bool, typer.Option("--check", help="the committed figures against the thesis' values")
    ] = False,
    evaluate: Annotated[
        bool, typer.Option("--evaluate", help="re-evaluate the kept policy or model behind it")
    ] = False,
    write_index: Annotated[
        bool, typer.Option("--write-index", help="write experiments/README.md from the registry")
    ] = False,
) -> None:
    """Reproduce the thesis' results: re-run a study and compare its figures with the committed
    ones, run quick variants, or check the committed figures against the thesis."""
    if list_:
        _list()
        return
    if write_index:
        index.README.write_text(index.readme())
        console.print(f"wrote {index.README}")
        return
    if all_ == (name is not None):
        raise typer.BadParameter("give a study NAME or --all (or --list, --write-index)")
    if all_ and not (quick or check):
        raise typer.BadParameter("--all runs the quick variants (--quick) or the --check")
    try:
        chosen = STUDIES if all_ else (study(name),)
    except KeyError as error:
        raise typer.BadParameter(error.args[0]) from error
    rows: list[runner.Row] = []
    failed: list[str] = []  # studies whose command failed
    if check:
        for entry in chosen:
            rows += runner.check(entry)
        console.print(_rows_table("committed figures against the thesis", rows, "thesis"))
    elif quick:
        for entry in chosen:
            if entry.quick is None:
                console.print(f"{entry.name}: no quick variant ({entry.no_quick})")
                continue
            try:
                found, seconds = runner.quick(entry)
            except runner.StudyFailed as error:
                console.print(f"{entry.name}: FAIL, {error}")
                failed.append(entry.name)
                continue
            console.print(f"{entry.name}: quick variant took {seconds:.0f} s")
            rows += found
        console.print(_rows_table("quick variants: figures produced", rows, "committed"))
    elif evaluate:
        try:
            rows, seconds = runner.evaluate(chosen[0])
        except runner.NotKept as error:  # not a usage error: the model is not in the repository
            report(str(error))
            raise typer.Exit(RUNTIME_EXIT) from error
        console.print(f"{chosen[0].name}: re-evaluated in {seconds:.0f} s")
        console.print(_rows_table("re-evaluation against the committed figures", rows, "committed"))
        if chosen[0].not_kept:  # the figures whose model is not kept
            console.print(f"not re-evaluated: {chosen[0].not_kept}")
    else:
        rows, seconds = runner.rerun(chosen[0])
        console.print(f"{chosen[0].name}: {seconds:.0f} s")
        console.print(_rows_table("re-run against the committed figures", rows, "committed"))
    if failed or not all(row.ok for row in rows):
        raise typer.Exit(1)
