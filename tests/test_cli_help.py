"""Every command's help: text for every option, no ``<bool>`` noise, the environment listed.

Walks the click tree typer builds (so a command added later is checked too) and renders each
``--help`` as a user sees it.
"""

from __future__ import annotations

import importlib
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import click
import pytest
import typer
from typer.testing import CliRunner

from aatest.cli import app

RUNNER = CliRunner()
ROOT = typer.main.get_command(app)
#: the environment variables a command's help must name (through envvar= or its text)
ENV_OF = {
    "run": ("AATEST_RECORDS", "AATEST_LAB", "AATEST_SIGNING_KEY", "AATEST_SIGNING_PASSPHRASE",
            "AATEST_OPERATOR"),
    "analyze": ("AATEST_RECORDS", "AATEST_LAB", "AATEST_SIGNING_KEY"),
    "report": ("AATEST_RECORDS", "AATEST_LAB", "AATEST_SIGNING_KEY"),
    "history": ("AATEST_RECORDS", "AATEST_LAB"),
    "records list": ("AATEST_RECORDS",),
    "station": ("AATEST_RECORDS", "AATEST_STATION_TOKEN"),
    "keygen": ("AATEST_SIGNING_PASSPHRASE",),
    "": ("AATEST_RECORDS", "AATEST_LAB", "AATEST_SIGNING_KEY", "AATEST_SIGNING_PASSPHRASE",
         "AATEST_STATION_TOKEN", "AATEST_WORKERS"),
}


def _commands(command: click.Command, path: tuple[str, ...] = ()) -> Iterator[
        tuple[tuple[str, ...], click.Command]]:
    yield path, command
    if isinstance(command, click.Group):
        for name, sub in command.commands.items():
            yield from _commands(sub, (*path, name))


COMMANDS = dict(_commands(ROOT))


def _help(path: tuple[str, ...]) -> str:
    result = RUNNER.invoke(app, [*path, "--help"], env={"COLUMNS": "240"})
    assert result.exit_code == 0, result.output
    return result.output


@pytest.mark.parametrize("path", sorted(COMMANDS), ids=lambda p: " ".join(p) or "aatest")
def test_every_option_has_help_and_no_type_noise(path: tuple[str, ...]) -> None:
    command = COMMANDS[path]
    silent = [p.opts[0] for p in command.params
              if isinstance(p, click.Option) and not p.hidden and not (p.help or "").strip()]
    assert not silent, f"aatest {' '.join(path)}: options without help text: {silent}"
    text = _help(path)
    assert "<bool>" not in text
    for flag in (p for p in command.params if isinstance(p, click.Option) and p.is_flag
                 and not p.hidden and p.name != "help" and not p.is_eager):
        assert flag.secondary_opts, f"{flag.opts[0]} is a flag without its --no- form"


@pytest.mark.parametrize("name", sorted(ENV_OF))
def test_help_names_the_environment(name: str) -> None:
    text = " ".join(_help(tuple(name.split())).split())  # rich folds long lines
    missing = [v for v in ENV_OF[name] if v not in text]
    assert not missing, f"aatest {name} --help does not name {missing}"


def test_version_names_python_and_the_key_libraries() -> None:
    result = RUNNER.invoke(app, ["--version"])
    assert result.exit_code == 0
    lines = result.stdout.splitlines()
    assert lines[0].startswith("aatest ") and lines[1].startswith("Python 3.")
    named = {line.split()[0] for line in lines[2:]}
    assert {"numpy", "scipy", "pydantic", "mcap", "sqlalchemy"} <= named


def test_station_lab_is_a_deprecated_alias_of_procedures(
        monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    serve_module = importlib.import_module("aatest.station.serve")  # the package shadows it
    seen: list[Any] = []
    monkeypatch.setattr(serve_module, "serve", seen.append)
    result = RUNNER.invoke(app, ["station", "--lab", str(tmp_path)])
    assert result.exit_code == 0 and "deprecated" in result.stderr
    assert "--procedures" in result.stderr and seen[0].lab_dir == tmp_path
    result = RUNNER.invoke(app, ["station", "--procedures", str(tmp_path)])
    assert result.exit_code == 0 and not result.stderr and seen[1].lab_dir == tmp_path
    assert "--lab" not in " ".join(_help(("station",)).split())
