"""Every committed result file's recorded ``command`` runs today: each script it names exists
and each ``pliant`` command it names is one of the CLI's, the options it gives accepted.
(Scripts moved into study folders left commands naming their old paths.)"""

from __future__ import annotations

import json
import re
import shlex
import subprocess
from pathlib import Path

import pytest
import typer

from pliant.cli import app

ROOT = Path(__file__).parents[2]
_ENV = re.compile(r"^[A-Z_][A-Z0-9_]*=")  # an environment assignment before the command


def _result_files() -> list[Path]:
    if (ROOT / ".git").exists():
        listing = subprocess.run(
            ["git", "ls-files", "experiments"], cwd=ROOT, capture_output=True, text=True
        )
        if listing.returncode == 0:
            return [ROOT / name for name in listing.stdout.split() if name.endswith(".json")]
    return sorted((ROOT / "experiments").rglob("*.json"))


def _commands(data, where: str = ""):
    """(JSON path, command) for every ``command`` key holding text or a list of words."""
    if isinstance(data, dict):
        for key, value in data.items():
            if key == "command" and (
                isinstance(value, str)
                or (isinstance(value, list) and value and isinstance(value[0], str))
            ):
                yield f"{where}/{key}", value
            else:
                yield from _commands(value, f"{where}/{key}")
    elif isinstance(data, list):
        for k, value in enumerate(data):
            yield from _commands(value, f"{where}/{k}")


RECORDED = [
    (path.relative_to(ROOT).as_posix(), where, command)
    for path in _result_files()
    for where, command in _commands(json.loads(path.read_text()))
]

_CLI = typer.main.get_command(app)


def _problem(words: list[str]) -> str | None:
    """Why the command `words` cannot run today (None: it can)."""
    while words and _ENV.match(words[0]):
        words = words[1:]
    if not words:
        return "no command"
    if words[0] == "python" and words[1:3] == ["-m", "pliant.cli"]:
        words = ["pliant", *words[3:]]
    if words[0] == "python":
        script = words[1] if len(words) > 1 else ""
        return None if script.endswith(".py") and (ROOT / script).is_file() else f"no {script}"
    if words[0] != "pliant":
        return f"neither python nor pliant: {words[0]!r}"
    command, args, name = _CLI, words[1:], "pliant"
    while hasattr(command, "list_commands") and args:  # a group (Typer's own click)
        sub = command.get_command(command.make_context(name, [], resilient_parsing=True), args[0])
        if sub is None:
            return f"{name} has no command {args[0]!r}"
        command, args, name = sub, args[1:], f"{name} {args[0]}"
    try:
        command.make_context(name, list(args))
    except Exception as error:  # Typer vendors click: its usage errors are no click's
        if not hasattr(error, "format_message"):
            raise
        if type(error).__name__ == "MissingParameter":
            # what a harness adds to each run (kill_resume.py's setup: --out per run)
            return None
        return f"{name}: {error.format_message()}"
    return None


def test_result_files_record_commands():
    assert len(RECORDED) > 300  # the scan found the files' commands
    assert any(command.startswith("pliant ") for _, _, command in RECORDED if command[0:1])


def test_every_recorded_command_names_an_existing_script_or_cli_command():
    problems = []
    for file, where, command in RECORDED:
        if isinstance(command, list):
            segments = [command]
        else:
            # the notes some commands carry in brackets ("(stopped at 6 000 steps)") are no words
            text = re.sub(r"\([^)]*\)", "", command)
            segments = [shlex.split(part) for part in re.split(r"&&|\|\||;", text)]
        for words in segments:
            why = _problem(words)
            if why is not None:
                problems.append(f"{file}:{where}: {why}")
    assert problems == []


@pytest.mark.parametrize(
    ("command", "why"),
    [
        ("python experiments/proxy_rl.py multigait", "no experiments/proxy_rl.py"),
        ("pliant proxy nothing", "has no command 'nothing'"),
        ("pliant proxy transfer multigait --no-such-option", "No such option"),
        ("", "no command"),
    ],
)
def test_a_stale_command_is_caught(command, why):
    assert why in (_problem(shlex.split(command)) or "")


def test_a_current_command_passes():
    assert _problem(shlex.split("PYTHONPATH=. python experiments/proxy/rl.py trunk")) is None
    assert _problem(["pliant", "proxy", "calibrate", "trunk", "--trials", "2"]) is None
