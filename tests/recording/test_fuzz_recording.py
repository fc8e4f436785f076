"""Fuzzing the recording reader with structural damage (beside test_recording's bit flips).

The golden v1 recording (two steps) is damaged by deleting, inserting or overwriting byte
ranges — anywhere, or in its summary section at the end where the reader finds its index and
the run's metadata — and read through: every step's table and DAQ log decoded. The reader
may refuse it only with an aatest error naming the file, never with another exception.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from fuzzing import budget, refused_cleanly
from hypothesis import given
from hypothesis import strategies as st

from aatest.engine.errors import AatestError
from aatest.recording import read_dataset

GOLDEN = Path(__file__).parent / "data" / "golden_v1" / "recording.mcap"
DATA = GOLDEN.read_bytes()

damage = st.tuples(st.sampled_from(["delete", "insert", "overwrite"]),
                   st.booleans(),  # in the summary section (the last 5 %) or anywhere
                   st.integers(0, 2**31), st.binary(min_size=1, max_size=64))


def damaged(edits: list[tuple[str, bool, int, bytes]]) -> bytes:
    data = bytearray(DATA)
    for kind, in_summary, position, payload in edits:
        start = len(data) * 95 // 100 if in_summary else 0
        at = start + position % max(len(data) - start, 1)
        if kind == "delete":
            del data[at:at + len(payload)]
        elif kind == "insert":
            data[at:at] = payload
        else:
            data[at:at + len(payload)] = payload
    return bytes(data)


def check(path: Path) -> None:
    try:
        dataset = read_dataset(path)
        for step in dataset.steps:
            assert len(step.table) > 0 and len(step.daq) > 0
    except AatestError as exc:
        assert refused_cleanly(exc), exc
        assert path.name in str(exc)


def _fuzz(root: Path, edits: list[tuple[str, bool, int, bytes]]) -> None:
    path = root / "recording.mcap"
    path.write_bytes(damaged(edits))
    check(path)


@budget(40)
@given(edits=st.lists(damage, min_size=1, max_size=3))
def test_fuzz_recording(tmp_path_factory: pytest.TempPathFactory,
                        edits: list[tuple[str, bool, int, bytes]]) -> None:
    _fuzz(tmp_path_factory.mktemp("fuzz"), edits)


@pytest.mark.slow
@budget(40 * 20)
@given(edits=st.lists(damage, min_size=1, max_size=5))
def test_fuzz_recording_long(tmp_path_factory: pytest.TempPathFactory,
                             edits: list[tuple[str, bool, int, bytes]]) -> None:
    _fuzz(tmp_path_factory.mktemp("fuzz"), edits)
