"""Who runs a procedure when nobody says: the name a run records and its report prints.

Why one rule in one place: ``aatest run`` and the station both record an operator for every
run (the report's traceability table names it), and an operator given neither on the command
line (``--operator``) nor in the station's start form must get the same name from both.
"""

from __future__ import annotations

import getpass
import os

OPERATOR_ENV = "AATEST_OPERATOR"


def default_operator() -> str:
    """``AATEST_OPERATOR``, else the login name, else ``"unknown"`` (a process with no user
    entry, e.g. in a container started with an arbitrary UID)."""
    try:
        return os.environ.get(OPERATOR_ENV) or getpass.getuser()
    except (KeyError, OSError):
        return "unknown"
