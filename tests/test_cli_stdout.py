"""A reader of stdout that goes away ends a command quietly (exit 141), not with a crash report;
a broken pipe anywhere else is still a defect (exit 4)."""

from __future__ import annotations

import io
import os
import subprocess
import sys
from pathlib import Path

import pytest
from typer.testing import CliRunner

from aatest.cli import app
from aatest.cli_stdout import EXIT_READER_GONE, ReaderAwareStdout, ReaderGone
from aatest.engine.errors import EXIT_INTERNAL
from aatest.engine.run import session

QUICK = Path(__file__).parent / "data" / "procedures" / "quick-sine-3-steps.yaml"


def _with_closed_reader(*args: str) -> subprocess.CompletedProcess[str]:
    """Run the CLI with stdout a pipe whose read end is closed before it writes anything."""
    read_end, write_end = os.pipe()
    os.close(read_end)
    try:
        return subprocess.run([sys.executable, "-m", "aatest.cli", *args], stdout=write_end,
                              stderr=subprocess.PIPE, stdin=subprocess.DEVNULL, text=True,
                              timeout=120, check=False)
    finally:
        os.close(write_end)


@pytest.mark.parametrize("args", [("plugins",), ("--help",), ("validate", str(QUICK)),
                                  ("plan", "--json", str(QUICK))],
                         ids=["plugins", "help", "validate", "plan-json"])
def test_a_closed_pipe_ends_the_command_quietly(args: tuple[str, ...]) -> None:
    done = _with_closed_reader(*args)
    assert done.returncode == EXIT_READER_GONE == 141
    assert done.stderr == ""  # no crash report, no "Exception ignored" from the last flush


def test_a_reader_that_leaves_after_the_first_line_is_quiet_too() -> None:
    """``aatest plugins | head -1`` as a shell runs it."""
    producer = subprocess.Popen([sys.executable, "-m", "aatest.cli", "plugins"],
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                stdin=subprocess.DEVNULL)
    assert producer.stdout is not None and producer.stderr is not None
    first = producer.stdout.readline()
    producer.stdout.close()
    code = producer.wait(timeout=120)
    stderr = producer.stderr.read()
    producer.stderr.close()
    assert first == b"turntable:\n"
    # the listing is short: it may be written whole into the pipe's buffer before it closes
    assert code in (0, EXIT_READER_GONE) and stderr == b""


def test_an_open_pipe_gets_the_whole_output() -> None:
    done = subprocess.run([sys.executable, "-m", "aatest.cli", "plan", "--json", str(QUICK)],
                          capture_output=True, text=True, timeout=120, check=False)
    assert done.returncode == 0, done.stderr
    assert done.stdout.rstrip().endswith("}")


class _ClosedPipe(io.StringIO):
    def flush(self) -> None:
        raise BrokenPipeError(32, "Broken pipe")


def test_only_stdout_writes_become_reader_gone() -> None:
    stdout = ReaderAwareStdout(_ClosedPipe())
    assert stdout.write("x") == 1  # buffered: the pipe is only met on flush
    with pytest.raises(ReaderGone):
        stdout.flush()
    assert not issubclass(ReaderGone, Exception)  # no `except Exception` swallows it


def test_a_broken_pipe_elsewhere_is_an_internal_error(monkeypatch: pytest.MonkeyPatch,
                                                      tmp_path: Path) -> None:
    def lost_link(*_args: object, **_kwargs: object) -> None:
        raise BrokenPipeError(32, "Broken pipe")

    monkeypatch.setattr(session, "prepare", lost_link)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    result = CliRunner().invoke(app, ["validate", str(QUICK)])
    assert result.exit_code == EXIT_INTERNAL
    assert result.output.startswith("internal error: BrokenPipeError")
