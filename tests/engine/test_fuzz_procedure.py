"""Fuzzing the procedure loader, planner and envelope check (what ``aatest validate`` runs).

Mutations of the shipped procedures — a value replaced by a hostile scalar, a line removed or
duplicated, the text cut short, bytes of garbage appended — must either validate or be refused
with located problems (``FILE:LINE:COLUMN``, exit 2); nothing may raise anything else.
"""

from __future__ import annotations

import re
from importlib import resources
from pathlib import Path

import pytest
from fuzzing import budget, refused_cleanly
from hypothesis import given
from hypothesis import strategies as st

from aatest.engine.errors import AatestError, ProblemsError
from aatest.engine.run.session import prepare

SHIPPED = sorted(Path(str(resources.files("aatest") / "procedures")).glob("*.yaml"))
HOSTILE = ["1e+308", "-1e+308", "0", "-1", ".nan", ".inf", "99999999999999999999999", "''",
           "[]", "{}", "null", "true", "x", "1e-320", "[1, [2, [3]]]", "&a 1", "*a", "!!binary x",
           "!!python/object:os.system x", "'\\x00'", "2020-01-01", "0x10", "1_000", "~"]

mutation = st.tuples(st.sampled_from(["value", "drop", "repeat", "cut", "garbage"]),
                     st.integers(0, 400), st.sampled_from(HOSTILE), st.binary(max_size=30))


def mutate(text: str, kind: str, where: int, value: str, garbage: bytes) -> str:
    lines = text.splitlines()
    i = where % len(lines)
    if kind == "value":
        lines[i] = re.sub(r"(:\s+)(\S.*)$", lambda m: m.group(1) + value, lines[i], count=1)
    elif kind == "drop":
        del lines[i]
    elif kind == "repeat":
        lines.insert(i, lines[i])
    elif kind == "cut":
        return text[: where * len(text) // 400]
    else:
        return text + garbage.decode("utf-8", "replace")
    return "\n".join(lines) + "\n"


def check(path: Path) -> None:
    try:
        prepare(path, None)
    except AatestError as exc:
        assert refused_cleanly(exc), exc
        if isinstance(exc, ProblemsError):
            assert all(str(p).startswith(f"{p.file}:{p.line}:{p.column}:") for p in exc.problems)


def _fuzz(root: Path, source: Path, mutations: list[tuple[str, int, str, bytes]]) -> None:
    text = source.read_text()
    for kind, where, value, garbage in mutations:
        text = mutate(text, kind, where, value, garbage) or "\n"
    path = root / source.name
    path.write_text(text, encoding="utf-8")
    check(path)


@budget(60)
@given(source=st.sampled_from(SHIPPED), mutations=st.lists(mutation, min_size=1, max_size=3))
def test_fuzz_procedure(tmp_path_factory: pytest.TempPathFactory, source: Path,
                        mutations: list[tuple[str, int, str, bytes]]) -> None:
    _fuzz(tmp_path_factory.mktemp("fuzz"), source, mutations)


@pytest.mark.slow
@budget(60 * 20)
@given(source=st.sampled_from(SHIPPED), mutations=st.lists(mutation, min_size=1, max_size=5))
def test_fuzz_procedure_long(tmp_path_factory: pytest.TempPathFactory, source: Path,
                             mutations: list[tuple[str, int, str, bytes]]) -> None:
    _fuzz(tmp_path_factory.mktemp("fuzz"), source, mutations)
