"""Files written atomically: under a temporary name in their own folder, flushed to the disk
(``fsync``), then moved over the target with `os.replace` and the folder's entry flushed too,
so that a reader, a crash or a power cut finds the old file or the whole new one, never a
part."""

from __future__ import annotations

import hashlib
import json
import math
import os
import pickle
import re
import uuid
import zipfile
import zlib
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TypeVar

import numpy as np

T = TypeVar("T")


def fsync_path(path: str | os.PathLike) -> None:
    """Flush a file's (or a folder's entries') data to the disk; a file system that cannot
    (some network or virtual ones refuse a folder) is left to its own guarantees."""
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def replace(tmp: str | os.PathLike, path: str | os.PathLike) -> None:
    """Move the finished temporary file (or folder) `tmp` onto `path` durably: `tmp`'s data
    reaches the disk before the rename (a folder's files and entries), and the rename before
    this returns."""
    tmp = Path(tmp)
    if tmp.is_dir():
        for inner in sorted(tmp.rglob("*"), reverse=True):
            fsync_path(inner)
    fsync_path(tmp)
    os.replace(tmp, path)
    fsync_path(Path(path).parent)


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
        replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def write_json(path: str | os.PathLike, data, *, indent: int | None = 1, **kwargs) -> None:
    """`json.dumps(data, indent=indent, **kwargs)` written to `path` atomically."""
    text = json.dumps(data, indent=indent, **kwargs)
    with atomic_path(path) as tmp:
        tmp.write_text(text)


#: Significant digits of a series in a result file (:func:`write_results`): a float32's
#: precision, finer than any figure is quoted at or compared within.
SERIES_DIGITS = 7
#: The numbers a list holds (itself, or its lists of numbers) to be a series: trajectories,
#: time lines, per-episode values; shorter ones (a position, a gain vector) keep every digit.
SERIES_LENGTH = 32

_TOKEN = r"(?:-?\d+(?:\.\d+)?(?:[eE][+-]?\d+)?|-?Infinity|NaN|true|false|null)"
_FLAT_LIST = re.compile(rf"\[\n\s*({_TOKEN}(?:,\n\s*{_TOKEN})*)\n\s*\]")


def _numbers(value) -> int | None:
    """How many numbers `value` holds if it is a list of numbers or of such lists, else None."""
    if isinstance(value, bool) or not isinstance(value, list):
        return 1 if isinstance(value, int | float) and not isinstance(value, bool) else None
    total = 0
    for item in value:
        count = _numbers(item)
        if count is None:
            return None
        total += count
    return total


def _rounded(value, digits: int):
    if isinstance(value, list):
        return [_rounded(item, digits) for item in value]
    if isinstance(value, float) and math.isfinite(value):
        return float(f"{value:.{digits}g}")
    return value


def compact_series(data, digits: int = SERIES_DIGITS, length: int = SERIES_LENGTH):
    """`data` (JSON-like; NumPy arrays and scalars become lists and numbers) with the floats of
    every series (a list of numbers, or of lists of numbers, holding at least `length`)
    rounded to `digits` significant digits; every other number (a figure, a setting) as it
    is."""
    if isinstance(data, np.ndarray | np.generic):
        data = data.tolist()
    if isinstance(data, dict):
        return {key: compact_series(value, digits, length) for key, value in data.items()}
    if isinstance(data, list | tuple):
        data = [compact_series(item, digits, length) for item in data]
        count = _numbers(data)
        return _rounded(data, digits) if count is not None and count >= length else data
    return data


def write_results(path: str | os.PathLike, data, *, digits: int = SERIES_DIGITS, **kwargs) -> None:
    """A result file: :func:`write_json` of :func:`compact_series` of `data`, each list of
    numbers on one line (a series is about a third of its size written with 17 digits, one
    number a line); what the registry reads as figures (single numbers) keeps every digit."""
    text = json.dumps(compact_series(data, digits), indent=1, **kwargs)
    text = _FLAT_LIST.sub(lambda m: "[" + re.sub(r",\n\s*", ", ", m[1]) + "]", text)
    with atomic_path(path) as tmp:
        tmp.write_text(text)


#: The file of a folder written by :func:`write_manifest`: each file's size and SHA-256.
MANIFEST = "manifest.json"

# What reading a damaged file raises, by the readers Pliant uses (zip, pickle, NumPy, HDF5,
# JSON, PyTorch, SB3's asserts, zlib for a compressed member): converted into a
# CorruptFileError naming the file.
_DAMAGE = (
    AssertionError,
    EOFError,
    ValueError,
    TypeError,
    KeyError,
    AttributeError,
    IndexError,
    ImportError,
    RuntimeError,
    pickle.UnpicklingError,
    zipfile.BadZipFile,
    zlib.error,
    UnicodeDecodeError,
)


def sha256(path: str | os.PathLike) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def write_manifest(folder: str | os.PathLike) -> None:
    """Record the size and SHA-256 of every file under `folder` in its manifest (atomically):
    :func:`check_manifest` then tells an intact folder from a damaged one."""
    folder = Path(folder)
    files = {
        p.relative_to(folder).as_posix(): {"bytes": p.stat().st_size, "sha256": sha256(p)}
        for p in sorted(folder.rglob("*"))
        if p.is_file() and p.name != MANIFEST
    }
    write_json(folder / MANIFEST, {"files": files})


def check_manifest(folder: str | os.PathLike) -> bool:
    """Check every file of `folder` against its manifest; False when it has none (a folder
    written before manifests existed).

    Raises:
        CorruptFileError: naming the first file missing, of another size or another hash, or
            the manifest itself when it cannot be read.
    """
    from pliant.errors import CorruptFileError

    folder = Path(folder)
    manifest = folder / MANIFEST
    if not manifest.is_file():
        return False
    try:
        files = json.loads(manifest.read_text())["files"]
        items = [(name, int(e["bytes"]), str(e["sha256"])) for name, e in files.items()]
    except (OSError, *_DAMAGE) as exc:
        raise CorruptFileError(f"{manifest}: not a readable manifest ({exc})", manifest) from exc
    for name, size, digest in items:
        path = folder / name
        if not path.is_file():
            raise CorruptFileError(f"{path}: missing (listed in {manifest})", path)
        if path.stat().st_size != size:
            raise CorruptFileError(
                f"{path}: {path.stat().st_size} bytes where {size} were written (truncated or"
                " overwritten)",
                path,
            )
        if sha256(path) != digest:
            raise CorruptFileError(f"{path}: its content changed since it was written", path)
    return True


def read_checked(
    path: str | os.PathLike, read: Callable[[Path], T], what: str, error: type | None = None
) -> T:
    """`read(path)`, with an empty or damaged file reported as an `error` (default
    CorruptFileError) naming it and `what` it should be, the file in its ``path`` attribute
    (a missing file stays FileNotFoundError, Pliant's own errors pass)."""
    from pliant.errors import CorruptFileError, PliantError

    path = Path(path)
    error = error or CorruptFileError

    def damaged(message: str) -> Exception:
        exc = error(message)
        exc.path = path
        return exc

    if path.is_file() and path.stat().st_size == 0:
        raise damaged(f"{path}: an empty file, not {what}")
    try:
        return read(path)
    except (FileNotFoundError, PliantError):
        raise
    except (OSError, *_DAMAGE) as exc:
        raise damaged(
            f"{path}: not {what} (truncated or corrupt?): {type(exc).__name__}: {exc}"
        ) from exc


def save_npz(path: str | os.PathLike, *, compressed: bool = False, **arrays) -> Path:
    """NumPy's ``savez`` (or ``savez_compressed``) of `arrays` to `path`, atomically; `path`
    gets NumPy's ``.npz`` ending when it lacks it. Returns the path written."""
    path = Path(path)
    if path.suffix != ".npz":
        path = path.with_name(path.name + ".npz")
    with atomic_path(path) as tmp:
        (np.savez_compressed if compressed else np.savez)(tmp, **arrays)
    return path


def load_npz(path: str | os.PathLike, what: str, error: type | None = None) -> dict:
    """Every array of an ``.npz`` file, read now (each member's CRC-32 checked), no pickles;
    a damaged file raises `error` (default CorruptFileError) naming it and `what` it is."""

    def read(p: Path) -> dict:
        with np.load(p, allow_pickle=False) as data:
            return {name: data[name] for name in data.files}

    return read_checked(path, read, what, error)
