"""Files written atomically: under a temporary name in their own folder, then moved over the
target with `os.replace`, so that a reader (or a crash) finds the old file or the whole new
one, never a part."""

from __future__ import annotations

import json
import os
import uuid
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path


@contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary path next to `path`; on success move it onto `path`, else delete it.

    The temporary name keeps the suffix of `path`, so writers that choose a format by
    extension still work. Missing parent directories are created.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.stem}.{uuid.uuid4().hex[:12]}.tmp{path.suffix}")
    try:
        yield tmp
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def write_json(path: str | os.PathLike, data, *, indent: int | None = 1, **kwargs) -> None:
    """`json.dumps(data, indent=indent, **kwargs)` written to `path` atomically."""
    text = json.dumps(data, indent=indent, **kwargs)
    with atomic_path(path) as tmp:
        tmp.write_text(text)
