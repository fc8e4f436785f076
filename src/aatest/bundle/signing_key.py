"""Which key signs a run's report, and whether a procedure's ask for a signature can be met.

Why a module of its own: ``aatest run``, ``validate`` (its preflight), the station and
``keygen`` read the same two environment variables and the same rule — the key named on the
command line, else ``AATEST_SIGNING_KEY``, else none (an unsigned report) — and a procedure
that asks for a signed report with no key is refused before anything moves, at the line of
its ``report.sign``.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from aatest.engine.errors import Problem
from aatest.positioned_yaml import locate

SIGNING_KEY_ENV = "AATEST_SIGNING_KEY"
PASSPHRASE_ENV = "AATEST_SIGNING_PASSPHRASE"


def signing_key(explicit: Path | None) -> Path | None:
    """The signing key: ``explicit`` (``--sign-key``), else ``AATEST_SIGNING_KEY``, else None.

    None leaves the report unsigned (a warning, not an error: a bench run need not be signed).
    """
    if explicit is not None:
        return explicit
    env = os.environ.get(SIGNING_KEY_ENV)
    return Path(env) if env else None


def signing_problems(proc: Any, key: Path | None) -> list[Problem]:
    """A procedure that asks for a signed report (``report.sign: true``) with no signing key
    configured: its run could only give an unsigned report, so it is refused at
    ``report.sign``. ``key``: the key the run would sign with (None: none configured)."""
    if key is not None or not proc.report.sign:
        return []
    line, col = locate(proc.source_tree, ("report", "sign")) if proc.source_tree else (1, 1)
    return [Problem(proc.source_file or f"<{proc.procedure}>", line, col, "report.sign",
                    "the procedure asks for a signed report and no signing key is configured: "
                    f"give --sign-key or {SIGNING_KEY_ENV}, or set report.sign: false")]
