"""``python -m pliant.cli ...``: the ``pliant`` command."""

from pliant.cli import app

app()
