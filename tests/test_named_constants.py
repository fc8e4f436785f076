"""Rig defaults and numerical factors are named once, not typed out again.

``aatest.rig_defaults`` states the documented rig (2 kHz logging, axis limits, log capacity) and
``aatest.numerics`` the 95 % factors and the guard against zero; a number with one of these
meanings written as a literal anywhere else can drift from its single statement unnoticed.
The scan reads every float literal of ``src/aatest`` (docstrings and strings are not numbers).
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

import aatest
from aatest import numerics, rig_defaults

SOURCE = Path(aatest.__file__).parent
#: literal → the name that states it (wherever it appears: these values have one meaning)
NAMED: dict[float, str] = {
    numerics.Z95: "aatest.numerics.Z95",
    1.959964: "aatest.numerics.Z95",
    numerics.K95: "aatest.numerics.K95",
    numerics.TINY: "aatest.numerics.TINY",
}
#: where the names are stated
HOMES = {"rig_defaults.py", "numerics.py"}


#: the log rate is flagged where it is assigned to a rate (2000 means other things too: ppm)
RATE = rig_defaults.LOG_RATE_HZ


def _rate_targets(node: ast.AST) -> list[tuple[str, ast.AST]]:
    """(name, value) of an assignment or keyword argument: what a literal is given to."""
    if isinstance(node, ast.keyword) and node.arg is not None:
        return [(node.arg, node.value)]
    if isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name) and node.value:
        return [(node.target.id, node.value)]
    if isinstance(node, ast.Assign):
        return [(t.id, node.value) for t in node.targets if isinstance(t, ast.Name)]
    return []


def literals_named_elsewhere(source: str) -> list[tuple[int, float]]:
    """(line, value) of every float literal in ``source`` that has a name: one of
    :data:`NAMED` anywhere, or the log rate given to a name that says rate or Hz."""
    tree = ast.parse(source)
    found = [(node.lineno, node.value) for node in ast.walk(tree)
             if isinstance(node, ast.Constant) and isinstance(node.value, float)
             and node.value in NAMED]
    for node in ast.walk(tree):
        for name, value in _rate_targets(node):
            if "rate" in name.lower() or name.lower().endswith("_hz"):
                found += [(c.lineno, c.value) for c in ast.walk(value)
                          if isinstance(c, ast.Constant) and c.value == RATE
                          and isinstance(c.value, float)]
    return found


def test_named_numbers_are_not_typed_out_again() -> None:
    """No module but their home writes the log rate, the 95 % factors or the zero guard."""
    found = [f"{path.relative_to(SOURCE)}:{line}: {value!r} "
             f"(use {NAMED.get(value, 'aatest.rig_defaults.LOG_RATE_HZ')})"
             for path in sorted(SOURCE.rglob("*.py")) if path.name not in HOMES
             for line, value in literals_named_elsewhere(path.read_text(encoding="utf-8"))]
    assert not found, "\n".join(found)


@pytest.mark.parametrize(("source", "expected"), [
    ("x = max(y, 1e-300)", [(1, 1e-300)]),
    ("rate_hz: float = 2000.0", [(1, 2000.0)]),
    ("sample_rate_hz: float = Field(2000.0, gt=0)", [(1, 2000.0)]),
    ("step(sample_rate_hz=2000.0)", [(1, 2000.0)]),
    ("MAX_DRIFT_PPM = 2000.0", []),
    ("ci = [d - 1.96 * u, d + 1.96 * u]", [(1, 1.96), (1, 1.96)]),
    ('"""Sampled at 2000.0 Hz."""\nn = 2000', []),
], ids=["guard", "rate", "rate-field", "rate-keyword", "ppm", "coverage-factor",
        "docstring-and-int"])
def test_the_scan_finds_float_literals_only(source: str, expected: list[tuple[int, float]]) -> None:
    """The scan sees float literals in code, not numbers inside strings or integer counts."""
    assert sorted(literals_named_elsewhere(source)) == sorted(expected)


def test_the_mcap_chunk_size_is_stated_once() -> None:
    """The recording's chunk size (``aatest.recording.channels.CHUNK_BYTES``) is assigned in
    one module only: the preview chunks and the data chunks are sized alike."""
    homes = sorted(str(p.relative_to(SOURCE)) for p in SOURCE.rglob("*.py")
                   for node in ast.walk(ast.parse(p.read_text()))
                   if isinstance(node, ast.Assign | ast.AnnAssign)
                   for target in (node.targets if isinstance(node, ast.Assign) else [node.target])
                   if isinstance(target, ast.Name) and target.id == "CHUNK_BYTES")
    assert homes == ["recording/channels.py"]
