"""Docs pages: guides (how to use a capability) stay short, and study reports (what a study
measured beside the thesis) sit apart under docs/studies/, each listed in the site's nav."""

from __future__ import annotations

from pathlib import Path

import yaml

DOCS = Path(__file__).parents[2] / "docs"
GUIDE_LINES = 400


def test_no_guide_page_is_over_400_lines():
    long = {
        str(page.relative_to(DOCS)): n
        for page in DOCS.rglob("*.md")
        if "studies" not in page.relative_to(DOCS).parts
        and (n := len(page.read_text().splitlines())) > GUIDE_LINES
    }
    assert long == {}, f"guide pages over {GUIDE_LINES} lines: move their results to docs/studies/"


def test_every_study_report_is_in_the_nav():
    text = (DOCS.parent / "mkdocs.yml").read_text()
    nav = yaml.safe_load("nav:" + text.split("\nnav:")[1].split("\nextra_javascript:")[0])["nav"]
    listed = set()

    def walk(node):
        if isinstance(node, str):
            listed.add(node)
        elif isinstance(node, dict):
            for value in node.values():
                walk(value)
        elif isinstance(node, list):
            for value in node:
                walk(value)

    walk(nav)
    reports = {str(p.relative_to(DOCS)) for p in (DOCS / "studies").glob("*.md")}
    assert reports and reports <= listed, reports - listed
