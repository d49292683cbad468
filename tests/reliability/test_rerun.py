"""Issue 22's ten classes of failure re-run with fresh examples (rerun_cases): every case of a
class passes, each crash-prone one in a child interpreter. Slow (minutes a class)."""

from __future__ import annotations

import pytest
import rerun_cases


@pytest.mark.slow
@pytest.mark.parametrize("k", range(1, 11), ids=lambda k: f"class{k}")
def test_every_fresh_case_of_the_class_passes(k, tmp_path, monkeypatch):
    monkeypatch.setattr(rerun_cases, "TMP", tmp_path)
    cases = rerun_cases.run_class(k)
    assert cases, f"class {k} ran no case"
    assert [f"{name}: {detail[:300]}" for _, name, ok, detail in cases if not ok] == []
