"""The documentation never rots: the site builds strictly, every Python block of the docs runs,
and the gallery lists every registered robot (the tutorials: test_tutorials_*.py)."""

from __future__ import annotations

import importlib.util
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).parents[2]
DOCS = ROOT / "docs"
PAGES = sorted(DOCS.rglob("*.md"))
SHARED = ROOT.parent / "shared"  # third-party reference data beside the checkout (CI has it)
NEEDS_SHARED = pytest.mark.skipif(
    not SHARED.is_dir(),
    reason="reads SOFA's reference scenes and meshes from ../shared (the project's CI places "
    "them beside the checkout; SOFA's public scenes, not redistributed here)",
)
BLOCKS = [
    pytest.param(
        code,
        id=f"{page.relative_to(DOCS)}:{k}",
        marks=[NEEDS_SHARED] if "../shared" in code else [],
    )
    for page in PAGES
    for k, code in enumerate(re.findall(r"```python\n(.*?)```", page.read_text(), flags=re.S))
    if not code.lstrip().startswith("--8<--")
]


@pytest.mark.skipif(importlib.util.find_spec("mkdocs") is None, reason="mkdocs not installed")
def test_site_builds_strictly(tmp_path):
    result = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "-d", str(tmp_path / "site")],
        cwd=ROOT,
        capture_output=True,
        text=True,
        env={**os.environ, "NO_MKDOCS_2_WARNING": "1"},
    )
    assert result.returncode == 0, result.stderr[-3000:]
    assert (tmp_path / "site" / "reference" / "model" / "index.html").is_file()


@pytest.mark.parametrize("code", BLOCKS)
def test_docs_example_runs(code):
    exec(compile(code, "docs", "exec"), {})


def test_gallery_lists_every_robot():
    sys.path.insert(0, str(DOCS))
    try:
        from gen_gallery import page
    finally:
        sys.path.pop(0)
    from pliant import robots

    assert (DOCS / "gallery.md").read_text() == page(sorted(robots.ROBOTS))
    for name in robots.ROBOTS:
        assert (DOCS / "assets" / "gallery" / f"{name}.png").is_file(), name
