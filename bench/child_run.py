"""Run a bench script again in a fresh process on another checkout and read its JSON line.

The ``--compare`` modes of the benches time a baseline checkout and this one side by side:
each round is a fresh interpreter whose ``PYTHONPATH`` starts with that checkout's ``src``,
and the child prints one JSON document as its last line. :func:`leaves` lays two such
outputs side by side, value by value.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any


def child_json(script: str, src: Path | None, argv: list[str], label: str) -> dict[str, Any]:
    """Run ``script argv`` with ``src`` (when given) first on ``PYTHONPATH``; its last stdout
    line as JSON. A failing child ends the bench with its stderr, under ``label``."""
    env = dict(os.environ)
    if src is not None:
        env["PYTHONPATH"] = os.pathsep.join([str(src), *filter(None, [env.get("PYTHONPATH")])])
    proc = subprocess.run([sys.executable, script, *argv], env=env, check=False,
                          capture_output=True, text=True)
    if proc.returncode != 0:
        raise SystemExit(f"{label} on {src or 'this checkout'} failed:\n{proc.stderr}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def leaves(value: Any, path: str = "") -> Iterator[tuple[str, Any]]:
    """Every leaf of a nested output (dicts, lists, tuples) with its path (``.a.b[3]``): what
    two checkouts' outputs are compared by."""
    if isinstance(value, dict):
        for key, item in value.items():
            yield from leaves(item, f"{path}.{key}")
    elif isinstance(value, list | tuple):
        for i, item in enumerate(value):
            yield from leaves(item, f"{path}[{i}]")
    else:
        yield path, value
