"""What every ``pliant`` command shares: one red line per failure, and option checks at entry.

A failure ends the command with one line on stderr, ``error: <cause>``, and exit status 2 for
a usage error (a bad option or argument, found before any work) or 1 for a runtime one (a
:class:`~pliant.errors.PliantError`, a file that cannot be written, or an unexpected
exception, named as such). ``pliant --debug ...`` (or ``PLIANT_DEBUG=1``) lets the exception
through with its traceback instead.
"""

from __future__ import annotations

import json
import math
import os
import sys
from collections.abc import Callable
from pathlib import Path

import typer
import typer.core
from rich.console import Console
from rich.text import Text

from pliant.errors import PliantError, UnknownRobotError

USAGE_EXIT = 2
RUNTIME_EXIT = 1
INTERRUPTED_EXIT = 130

_stderr = Console(stderr=True, soft_wrap=True, highlight=False)


def _kinds(name: str) -> tuple[type[Exception], ...]:
    """The click exception class `name` typer raises: click's own, or the copy of click that
    recent typer versions carry (found from typer's classes, so click need not be installed)."""
    found = {c for c in typer.BadParameter.__mro__ if c.__name__ == name}
    found.update(c for c in typer.Abort.__mro__ if c.__name__ == name)
    return tuple(found)


_USAGE, _CLICK, _ABORT = _kinds("UsageError"), _kinds("ClickException"), _kinds("Abort")


def report(message: str) -> None:
    """Print `message` as the one red error line (newlines and runs of spaces folded)."""
    _stderr.print(Text("error: " + " ".join(str(message).split()), style="red"))


def debugging(args: list[str]) -> bool:
    """Whether tracebacks are wanted: ``--debug`` before the command, or PLIANT_DEBUG=1."""
    if os.environ.get("PLIANT_DEBUG", "") not in ("", "0"):
        return True
    for arg in args:  # the global options, up to the command's name
        if arg == "--debug":
            return True
        if not arg.startswith("-"):
            return False
    return False


class ErrorHandlingGroup(typer.core.TyperGroup):
    """The command group of ``pliant``: every exception out of a command, its sub-commands and
    their option parsing ends as one red line and an exit status (see the module's doc)."""

    def main(self, args=None, prog_name=None, complete_var=None, standalone_mode=True, **extra):
        args = list(sys.argv[1:] if args is None else args)
        if not standalone_mode or debugging(args):
            return super().main(args, prog_name, complete_var, standalone_mode, **extra)
        try:
            result = super().main(args, prog_name, complete_var, False, **extra)
        except _USAGE as exc:
            if type(exc).__name__ == "NoArgsIsHelpError":  # `pliant condensed`: its help
                exc.show()
                sys.exit(exc.exit_code)
            where = f" (see '{exc.ctx.command_path} --help')" if exc.ctx is not None else ""
            report(exc.format_message() + where)
            sys.exit(USAGE_EXIT)
        except _CLICK as exc:
            report(exc.format_message())
            sys.exit(exc.exit_code)
        except _ABORT:
            report("aborted")
            sys.exit(RUNTIME_EXIT)
        except KeyboardInterrupt:
            report("interrupted")
            sys.exit(INTERRUPTED_EXIT)
        except UnknownRobotError as exc:  # a robot argument: a usage error
            report(str(exc))
            sys.exit(USAGE_EXIT)
        except PliantError as exc:
            report(str(exc))
            sys.exit(RUNTIME_EXIT)
        except OSError as exc:  # an output that cannot be written: the cause is in the text
            report(f"{exc.strerror or exc}: {exc.filename}" if exc.filename else str(exc))
            sys.exit(RUNTIME_EXIT)
        except Exception as exc:  # a bug: still one line, the traceback with --debug
            report(
                f"unexpected {type(exc).__name__}: {exc} (a bug in Pliant; rerun with"
                " 'pliant --debug ...' for the traceback and report it)"
            )
            sys.exit(RUNTIME_EXIT)
        sys.exit(result if isinstance(result, int) else 0)


def command_group(help: str) -> typer.Typer:
    """A group of sub-commands (``pliant condensed``, ``trajopt``, ``proxy``, ``graph``): its
    help when called alone, no shell-completion options."""
    return typer.Typer(add_completion=False, no_args_is_help=True, help=help)


def _check(test: Callable[[float], bool], wanted: str) -> Callable:
    def callback(value):
        if value is None:
            return value
        values = value if isinstance(value, (list, tuple)) else [value]
        for v in values:
            if not test(v):
                raise typer.BadParameter(f"must be {wanted}, got {v!r}")
        return value

    return callback


positive = _check(lambda v: math.isfinite(v) and v > 0, "finite and > 0")
non_negative = _check(lambda v: math.isfinite(v) and v >= 0, "finite and >= 0")
at_least_one = _check(lambda v: v >= 1, ">= 1")
finite = _check(math.isfinite, "finite")
open_fraction = _check(lambda v: math.isfinite(v) and 0 < v < 1, "in (0, 1)")
fraction = _check(lambda v: math.isfinite(v) and 0 < v <= 1, "in (0, 1]")


def one_of(*names: str) -> Callable:
    """A callback refusing any value but `names` (checked before the command's work)."""

    def callback(value):
        if value is not None and value not in names:
            raise typer.BadParameter(f"must be one of {', '.join(names)}, got {value!r}")
        return value

    return callback


def numbers_list(text: str, what: str, *, count: int | None = None) -> list[float]:
    """Comma-separated finite numbers (`count` of them if given); BadParameter otherwise."""
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        raise typer.BadParameter(
            f"{what}: expected comma-separated numbers, got {text!r}"
        ) from None
    if not all(math.isfinite(v) for v in values):
        raise typer.BadParameter(f"{what}: the numbers must be finite, got {text!r}")
    if count is not None and len(values) != count:
        raise typer.BadParameter(f"{what}: expected {count} numbers, got {text!r}")
    return values


def output_folder(path: Path | None) -> Path | None:
    """Option callback: BadParameter unless `path` is a folder that exists or can be made."""
    if path is None:
        return None
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise typer.BadParameter(f"{str(path)!r} is a file, not a folder")
    existing = next((p for p in (path, *path.parents) if p.exists()), None)
    if existing is not None and not os.access(existing, os.W_OK | os.X_OK):
        raise typer.BadParameter(f"{str(path)!r}: {str(existing)!r} is not writable")
    return path


def output_file(path: Path | None) -> Path | None:
    """Option callback: BadParameter unless `path` can be written as a file (not a folder,
    in a folder that exists or can be made and is writable)."""
    if path is None:
        return None
    path = Path(path)
    if path.is_dir():
        raise typer.BadParameter(f"{str(path)!r} is a folder, not a file")
    existing = next((p for p in path.parents if p.exists()), None)
    if existing is not None and (
        not existing.is_dir() or not os.access(existing, os.W_OK | os.X_OK)
    ):
        raise typer.BadParameter(f"{str(path)!r}: {str(existing)!r} is not a writable folder")
    return path


def assignments(items: list[str], *, form: str = "KEY=VALUE", option: str = "") -> dict[str, str]:
    """``KEY=VALUE`` items (repeated options) as a dict of texts; BadParameter naming `option`
    (or saying what was expected) for an item without ``=`` or without a key."""
    out = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key:
            raise typer.BadParameter(
                f"{option} takes {form}, got {item!r}"
                if option
                else f"expected {form}, got {item!r}"
            )
        out[key] = value
    return out


def json_or_text(text: str):
    """A command-line value: JSON where it parses (numbers, lists, true/false), else text."""
    try:
        return json.loads(text)
    except json.JSONDecodeError:
        return text
