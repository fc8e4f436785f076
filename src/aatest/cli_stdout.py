"""Standard output whose reader may go away (``aatest plugins | head -1``).

A closed pipe is not a defect of aatest: the command stops quietly, as any Unix tool stopped by
``SIGPIPE`` does, instead of printing a crash report (exit 4). Python ignores ``SIGPIPE`` and
raises :class:`BrokenPipeError` from the failed write instead; restoring the signal's default
action would kill the process mid-run, skipping the rig's safe stop, so the write is turned
into :class:`ReaderGone` — a ``BaseException``, so that no ``except Exception`` (the CLI's
crash handler, a plugin's catch-all) mistakes it for an error — which unwinds through every
``finally`` (the rig stopped and closed, the recording kept) up to :func:`aatest.cli.main`.
Only writes to standard output are translated: a broken pipe anywhere else stays an error.
"""

from __future__ import annotations

import os
import signal
import sys
from typing import Any, TextIO

#: exit status when standard output's reader went away: 128 + SIGPIPE (141 on Linux and
#: macOS), what a shell reports for a tool stopped by the signal
EXIT_READER_GONE = 128 + int(getattr(signal, "SIGPIPE", 13))


class ReaderGone(BaseException):
    """Standard output's reader closed the pipe; the command stops without a word."""


class ReaderAwareStdout:
    """Delegates to the real ``sys.stdout``; a broken pipe on write or flush raises
    :class:`ReaderGone` (from the :class:`BrokenPipeError`)."""

    def __init__(self, stream: TextIO) -> None:
        self._stream = stream

    def write(self, text: str) -> int:
        try:
            return self._stream.write(text)
        except BrokenPipeError as exc:
            raise ReaderGone from exc

    def flush(self) -> None:
        try:
            self._stream.flush()
        except BrokenPipeError as exc:
            raise ReaderGone from exc

    def __getattr__(self, name: str) -> Any:
        return getattr(self._stream, name)


def silence_stdout() -> None:
    """Point file descriptor 1 at the null device, so the interpreter's last flush of what is
    still buffered cannot complain about the closed pipe on stderr."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.__stdout__.fileno() if sys.__stdout__ is not None else 1)
        os.close(devnull)
    except (OSError, ValueError):  # no real stdout (embedded, tests): nothing to silence
        pass
