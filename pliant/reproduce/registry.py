"""What a study is: the thesis result it reproduces, the command that makes it, a quick variant
that checks the pipeline in minutes, and the figures it writes, each read from a committed result
file (never typed in) beside the thesis' value and the departure from the thesis, stated.

A figure's ``path`` walks the JSON file: keys separated by ``/``, list indices as integers,
``field=value`` for the entries of a list whose field has that value (one at least), and ``*``
for every entry of a mapping or list; a path that reaches several numbers gives their mean
(three seeds' steps to solve, say). ``scale`` turns the stored number into the unit shown (100
for a fraction shown in %).
"""

from __future__ import annotations

import json
import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

ROOT = Path(__file__).parents[2]
"""The repository root: commands run there and result files are relative to it."""


class FigureError(LookupError):
    """A figure cannot be read: its file is missing, its path absent, or its value no number."""


@dataclass(frozen=True)
class Figure:
    """One number a study produces, beside the thesis' value.

    Args:
        name: what is measured, in the thesis' words.
        file: the result file, relative to the repository root.
        path: keys into the file's JSON, separated by ``/`` (``*`` for every entry,
            ``field=value`` for the entries of a list with that value: their mean).
        thesis: the thesis' value, in ``thesis_unit`` (``None`` where it gives none).
        unit: the unit of ours, after ``scale``.
        better: which way ours beats the thesis: ``lower``, ``higher`` or ``closer`` (within
            ``tolerance`` of it, relatively).
        tolerance: relative difference allowed between a re-run and the committed value (and,
            for ``closer``, between ours and the thesis').
        departure: how the study departs from the thesis' setting; required where ours does
            not meet the thesis' value or its unit differs.
        thesis_unit: the thesis' unit when it is not ours (then the values do not compare).
        scale: factor from the stored number to ``unit``.
        fmt: how a value is written (tables and the docs' quotes), see ``format``.
        docs: a docs page that quotes this figure: the test checks ``fmt`` of the file's value
            appears in it.
        protocol: where the number was selected (a checkpoint, a weight, a sampling box) on
            the evaluation it is reported on, or tested on data not drawn as the thesis' were:
            what departs from selecting on validation data and reporting on held-out data, the
            old and new values where it was re-run, or what re-running it would need.
    """

    name: str
    file: str
    path: str
    thesis: float | None
    unit: str
    better: Literal["lower", "higher", "closer"]
    tolerance: float
    departure: str = ""
    thesis_unit: str | None = None
    scale: float = 1.0
    fmt: str = "{:.3g}"
    docs: str | None = None
    protocol: str = ""

    def read(self, root: Path = ROOT, file: Path | None = None) -> float:
        """Our value: the number at ``path`` in ``file`` (default: the committed one), scaled."""
        target = file if file is not None else root / self.file
        try:
            data = json.loads(target.read_text())
        except FileNotFoundError as error:
            raise FigureError(f"{self.name}: no result file {target}") from error
        values = _walk(data, self.path.split("/"), self)
        if not values or not all(isinstance(v, int | float) and math.isfinite(v) for v in values):
            raise FigureError(f"{self.name}: {target}:{self.path} holds {values!r}, not numbers")
        return self.scale * sum(values) / len(values)

    def compares(self) -> bool:
        """Whether ours and the thesis' value are in one unit (and so can be compared)."""
        return self.thesis is not None and self.thesis_unit in (None, self.unit)

    def meets_thesis(self, ours: float) -> bool | None:
        """Whether ours is at least as good as the thesis' value (``None``: not comparable)."""
        if not self.compares():
            return None
        if self.better == "lower":
            return ours <= self.thesis
        if self.better == "higher":
            return ours >= self.thesis
        return abs(ours - self.thesis) <= self.tolerance * abs(self.thesis)

    def format(self, value: float, fmt: str | None = None) -> str:
        """``value`` written with ``fmt`` (default the figure's) as the docs write numbers:
        exponents short (4.78e-7), thousands (a ``,`` in ``fmt``) apart by spaces (40 000)."""
        text = (fmt or self.fmt).format(value).replace(",", " ")
        return re.sub(r"e([+-])0*(\d)", lambda m: "e" + m[1].lstrip("+") + m[2], text)

    def thesis_text(self) -> str:
        if self.thesis is None:
            return "-"
        # the thesis' value as the thesis gives it, not rounded to our precision
        fmt = "{:.0f}" if float(self.thesis).is_integer() else "{:.4g}"
        return f"{self.format(self.thesis, fmt)} {self.thesis_unit or self.unit}".rstrip()

    def ours_text(self, ours: float) -> str:
        return f"{self.format(ours)} {self.unit}".rstrip()


def _walk(data, keys: list[str], figure: Figure) -> list:
    if not keys:
        return [data]
    key, rest = keys[0], keys[1:]
    if key == "*":
        entries = data.values() if isinstance(data, dict) else data
        return [v for entry in entries for v in _walk(entry, rest, figure)]
    if isinstance(data, list) and "=" in key:  # the entries whose field equals the value
        field, value = key.split("=", 1)
        chosen = [e for e in data if isinstance(e, dict) and str(e.get(field)) == value]
        if not chosen:
            raise FigureError(f"{figure.name}: {figure.file}: no entry {key!r}")
        return [v for entry in chosen for v in _walk(entry, rest, figure)]
    try:
        child = data[int(key)] if isinstance(data, list) else data[key]
    except (KeyError, IndexError, ValueError, TypeError) as error:
        raise FigureError(f"{figure.name}: {figure.file} has no {figure.path!r}") from error
    return _walk(child, rest, figure)


@dataclass(frozen=True)
class Quick:
    """A small run of a study's pipeline, to check it still produces its figures.

    Args:
        command: shell command run at the repository root; ``{out}`` is a fresh folder.
        files: committed result file -> the file the quick run writes, relative to ``{out}``;
            the figures of these files must be read from the quick run's (values not compared:
            the quick run is smaller than the study).
        seconds: wall time measured on the project's shared 2-core machine.
        figures: the names of the figures it makes (empty: every figure of its files); a
            re-evaluation that makes only some (the models of the others not kept) names them.
    """

    command: str
    files: dict[str, str]
    seconds: float
    figures: tuple[str, ...] = ()

    def makes(self, figure: Figure) -> bool:
        """Whether this run writes `figure` (its file mapped, and named where names are given)."""
        return figure.file in self.files and (not self.figures or figure.name in self.figures)


@dataclass(frozen=True)
class Study:
    """One thesis result, the command that reproduces it and what it writes.

    Args:
        name: the study's name on the command line.
        thesis: the thesis' table or section.
        title: the result, in a line.
        command: the full study, at the repository root (runs in sequence where several).
        figures: the numbers it produces.
        quick: the quick variant, or ``None`` with ``no_quick`` saying why.
        no_quick: why there is no quick variant.
        docs: the docs page that reports the study.
        evaluate: re-evaluates the kept policy or model behind the figures from the repository
            alone (``pliant reproduce NAME --evaluate``), written into ``{out}``; its files'
            figures are compared with the committed ones within their tolerance. A policy is
            kept as a ``policy.npz`` (``pliant export-policy RUN experiments/results/STUDY/
            policy.npz``: the actor and normaliser alone, docs/learning.md) and named by its
            path in the command, e.g. ``pliant eval experiments/results/STUDY/policy.npz
            --episodes 100 --json {out}/evaluation.json`` or a study's script given the file
            (every loader of ``pliant.learn.evaluate.load_policy`` reads it); the kept files
            must be tracked and small (tests/interface/test_reproduce.py).
        not_kept: why the figures cannot be re-evaluated from the repository (the policy or
            model is not tracked, and what re-making it costs); beside a re-evaluation that
            names its figures, why the others cannot.
        retrain: the command that re-makes the policy or model not kept, where it is not the
            study's own ``command``.
    """

    name: str
    thesis: str
    title: str
    command: str
    figures: tuple[Figure, ...]
    quick: Quick | None = None
    no_quick: str = ""
    docs: str = ""
    evaluate: Quick | None = None
    not_kept: str = ""
    retrain: str = ""

    def retraining(self) -> str:
        """The command that re-makes the policy or model behind the figures (not kept)."""
        return self.retrain or self.command

    def __post_init__(self) -> None:
        if (self.quick is None) == (not self.no_quick):
            raise ValueError(f"study {self.name}: give a quick variant or the reason for none")
        if self.evaluate is not None and self.not_kept and not self.evaluate.figures:
            raise ValueError(f"study {self.name}: a re-evaluation and no kept model")
        if self.evaluate is not None and self.evaluate.figures:
            names = {figure.name for figure in self.figures}
            if not set(self.evaluate.figures) <= names:
                unknown = sorted(set(self.evaluate.figures) - names)
                raise ValueError(f"study {self.name}: re-evaluates no figure named {unknown}")
            if len(self.evaluate.figures) < len(self.figures) and not self.not_kept:
                raise ValueError(f"study {self.name}: says not why some figures are not kept")
        if self.retrain and not self.not_kept:
            raise ValueError(f"study {self.name}: a re-training command and nothing not kept")
        for figure in self.figures:
            if figure.thesis_unit not in (None, figure.unit) and not figure.departure:
                raise ValueError(f"{self.name}: {figure.name} in other units says no departure")
