"""Run a bench script again in a fresh process on another checkout and read its JSON line.

The ``--compare`` modes of the benches time a baseline checkout and this one side by side:
each round is a fresh interpreter whose ``PYTHONPATH`` starts with that checkout's ``src``,
and the child prints one JSON document as its last line. :func:`leaves` lays two such
outputs side by side, value by value.
"""

from __future__ import annotations

import argparse
import json
import os
import pickle
import subprocess
import sys
import tempfile
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


def plain(x: Any) -> Any:
    """``x`` as dicts, lists and floats (dataclasses by their fields), to compare across trees
    by :func:`leaves` (arrays by element, complex numbers as their two parts)."""
    if hasattr(x, "__dataclass_fields__"):
        return {k: plain(getattr(x, k)) for k in x.__dataclass_fields__}
    if isinstance(x, dict):
        return {str(k): plain(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [plain(v) for v in x]
    if hasattr(x, "tolist"):
        return plain(x.tolist())
    if isinstance(x, complex):
        return [x.real, x.imag]
    return x


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


def this_src(script: str) -> Path:
    """The ``src`` of the checkout whose ``bench/`` holds ``script``."""
    return Path(script).resolve().parents[1] / "src"


def checkout_arguments(doc: str | None, target: str, rounds: int, dumps: bool = True,
                       target_help: str | None = None) -> argparse.ArgumentParser:
    """The options every per-run bench takes: the run (``target``, its help), ``--rounds``
    (default ``rounds``), ``--compare BASE_SRC``, and the child's ``--json`` (and ``--dump
    FILE``, with ``dumps``: :func:`alternate` asks for both)."""
    parser = argparse.ArgumentParser(description=(doc or "").splitlines()[0])
    parser.add_argument(target, type=Path, help=target_help)
    parser.add_argument("--rounds", type=int, default=rounds)
    parser.add_argument("--compare", type=Path, default=None, metavar="BASE_SRC")
    if dumps:
        parser.add_argument("--dump", type=Path, default=None, help=argparse.SUPPRESS)
    parser.add_argument("--json", action="store_true", help=argparse.SUPPRESS)
    return parser


def against(script: str, base_src: Path, argv: list[str], label: str, processes: int
            ) -> tuple[dict[str, list[dict[str, Any]]], dict[str, Any]]:
    """:func:`alternate` of the checkout ``base_src`` (``base``) and this one (``this``)."""
    return alternate(script, {"base": base_src, "this": this_src(script)}, argv, label,
                     processes)


def alternate(script: str, checkouts: dict[str, Path], argv: list[str], label: str,
              processes: int) -> tuple[dict[str, list[dict[str, Any]]], dict[str, Any]]:
    """Run ``script argv --dump FILE --json`` on each checkout's ``src`` in turn, ``processes``
    times each (alternating, so a change of machine load hits both alike): every run's JSON
    by checkout, and each checkout's last dumped output (a pickle the script wrote) to compare
    the two by (:func:`leaves`)."""
    runs: dict[str, list[dict[str, Any]]] = {name: [] for name in checkouts}
    with tempfile.TemporaryDirectory() as tmp:
        dumps = {name: Path(tmp) / f"{name}.pickle" for name in checkouts}
        for _ in range(processes):
            for name, src in checkouts.items():
                runs[name].append(child_json(script, src, [*argv, "--dump", str(dumps[name]),
                                                           "--json"], label))
        # the benches' own pickles, written by the child a moment ago in our temporary folder
        outputs = {name: pickle.loads(dumps[name].read_bytes()) for name in checkouts}
    return runs, outputs
