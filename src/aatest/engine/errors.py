"""One exception tree for aatest.

Every error a user can cause or a rig can raise derives from :class:`AatestError`, carries the
process exit code the CLI must use, and also derives from the built-in it resembles so callers
may catch either. Library and vendor errors are translated at the plugin boundary with
``raise ... from exc``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import wraps
from pathlib import Path
from typing import Concatenate, ParamSpec, TypeVar

EXIT_OK = 0
EXIT_FINDING = 1
EXIT_BAD_INPUT = 2
EXIT_RIG_FAULT = 3
EXIT_INTERNAL = 4


@dataclass(frozen=True)
class Problem:
    """One located problem in an input file: ``FILE:LINE:COLUMN: field: message``."""

    file: str
    line: int
    column: int
    field: str
    message: str

    def __str__(self) -> str:
        where = f"{self.file}:{self.line}:{self.column}"
        if self.field:
            return f"{where}: {self.field}: {self.message}"
        return f"{where}: {self.message}"


class AatestError(Exception):
    """Base of every aatest error; ``exit_code`` is what the CLI returns."""

    exit_code: int = EXIT_BAD_INPUT


class InputError(AatestError, ValueError):
    """A user-supplied file or argument is wrong (exit 2)."""


class ProblemsError(InputError):
    """Several located problems in one input file, reported all at once."""

    def __init__(self, problems: list[Problem]) -> None:
        self.problems = list(problems)
        super().__init__("\n".join(str(p) for p in self.problems))


class ProcedureError(ProblemsError):
    """The procedure YAML is malformed or does not match the schema."""


class EnvelopeError(ProblemsError):
    """A planned step leaves the rig or sensor envelope."""


class ImportDataError(InputError):
    """A measured-data import directory or one of its CSV files is malformed."""

    def __init__(self, path: str | Path, message: str, line: int | None = None) -> None:
        self.path = str(path)
        self.line = line
        where = f"{self.path}:{line}" if line is not None else self.path
        super().__init__(f"{where}: {message}")


class RecordingError(InputError):
    """A recording is missing, truncated or not an aatest recording."""


class PluginError(AatestError, LookupError):
    """A plugin is missing, fails validation, or was given a bad configuration."""


class AnalysisError(AatestError, ValueError):
    """The data cannot support the requested analysis (e.g. no sync edges)."""


class RigFault(AatestError, RuntimeError):
    """The rig failed: connection lost, timeout, fault bit, bus-off (exit 3)."""

    exit_code = EXIT_RIG_FAULT


class StorageFault(RigFault):
    """The run directory cannot be written (disk full, I/O error): completed steps are kept."""


class EnvelopeRefused(RigFault):
    """A controller refused a command outside its limits (a rig-side guard tripped)."""


class VerificationFailed(AatestError):
    """A signed bundle does not verify (exit 1)."""

    exit_code = EXIT_FINDING


class RunAborted(RigFault):
    """An operator aborted the run; the rig was brought to its safe state as on a fault (exit 3)."""


P = ParamSpec("P")
T = TypeVar("T")
S = TypeVar("S")


def rig_boundary(method: Callable[Concatenate[S, P], T]) -> Callable[Concatenate[S, P], T]:
    """Translate every non-aatest error leaving a driver method into a one-line RigFault.

    The plugin boundary of docs/interfaces.md §1: whatever a vendor library, a socket or a
    partial frame throws (``ConnectionResetError``, timeouts, decode errors) ends as exit 3 with
    one reason line naming the plugin (its ``_where`` attribute) and the method that failed, so
    the engine brings the rig to its safe state and the run stays resumable. ``KeyboardInterrupt``
    and other ``BaseException`` pass through untouched.
    """

    @wraps(method)
    def wrapper(self: S, /, *args: P.args, **kwargs: P.kwargs) -> T:
        try:
            return method(self, *args, **kwargs)
        except AatestError:
            raise
        except Exception as exc:  # the translation boundary: every library error
            where = getattr(self, "_where", type(self).__name__)
            detail = " ".join(str(exc).split()) or "no detail"
            raise RigFault(f"{where}: {method.__name__} failed: "
                           f"{type(exc).__name__}: {detail}") from exc

    return wrapper
