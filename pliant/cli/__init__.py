"""The ``pliant`` command line: one module per command group, assembled here.

:mod:`~pliant.cli.run` (``run``, ``inverse``, ``view``), :mod:`~pliant.cli.bench`,
:mod:`~pliant.cli.planning` (``plan``), :mod:`~pliant.cli.reduction` (``reduce``),
:mod:`~pliant.cli.reproduce`, :mod:`~pliant.cli.learn` (``train``, ``eval``, ``enjoy``,
``export-policy``, ``tune``), and the groups :mod:`~pliant.cli.condensed`,
:mod:`~pliant.cli.trajopt`, :mod:`~pliant.cli.proxy` and :mod:`~pliant.cli.graph`;
:mod:`~pliant.cli.support` is what every command shares (one red line per failure, option
checks at entry). A command imports the code it runs when it runs, so that ``pliant --help``
starts quickly.
"""

from __future__ import annotations

from typing import Annotated

import typer

from pliant.cli import learn, run
from pliant.cli.bench import bench
from pliant.cli.condensed import app as condensed_app
from pliant.cli.graph import app as graph_app
from pliant.cli.planning import plan
from pliant.cli.proxy import app as proxy_app
from pliant.cli.reduction import reduce_command
from pliant.cli.reproduce import reproduce_command
from pliant.cli.run import open_viewer
from pliant.cli.support import ErrorHandlingGroup
from pliant.cli.trajopt import app as trajopt_app

__all__ = ["app", "open_viewer"]

app = typer.Typer(
    cls=ErrorHandlingGroup,
    add_completion=False,
    no_args_is_help=True,
    help="Simulate, control and benchmark FEM soft robots.",
)
app.add_typer(condensed_app, name="condensed")
app.command()(plan)
app.add_typer(trajopt_app, name="trajopt")
app.command("reduce")(reduce_command)
app.command("reproduce")(reproduce_command)
app.command("train")(learn.train)
app.command("eval")(learn.eval_)
app.command("enjoy")(learn.enjoy)
app.command("export-policy")(learn.export_policy)
app.command("tune")(learn.tune)
app.add_typer(proxy_app, name="proxy")
app.add_typer(graph_app, name="graph")
app.command()(run.run)
app.command()(run.inverse)
app.command()(bench)
app.command()(run.view)


@app.callback()
def main(
    debug: Annotated[
        bool, typer.Option("--debug", help="on failure, show the traceback (not one line)")
    ] = False,
) -> None:
    """Simulate, control and benchmark FEM soft robots."""
