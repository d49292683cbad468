"""MkDocs hook (``hooks:`` in mkdocs.yml): fills docs/results.md's tables from the registry and
the committed result files at build time, so the site's thesis-against-ours figures are the
files' own."""

from __future__ import annotations

from pliant.reproduce import index

MARKERS = {
    "<!-- registry: figures -->": index.figures_table,
    "<!-- registry: studies -->": index.studies_table,
}


def on_page_markdown(markdown: str, page, **kwargs) -> str:
    """Replace the registry's markers in a page with the tables they name."""
    for marker, table in MARKERS.items():
        if marker in markdown:
            markdown = markdown.replace(marker, table())
    return markdown
