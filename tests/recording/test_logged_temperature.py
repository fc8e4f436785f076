"""The results' logged-temperature summary is tallied by the analysis pass's one decode.

The sync pass decodes every recorded step (in forked workers when it can); the temperature
tallies ride along that decode (:func:`aatest.recording.temperatures.watch`), so building the
summary afterwards decodes nothing, and it equals the summary read step by step on its own.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from aatest.engine.analysis.passes import run_analyses
from aatest.recording import read_dataset
from aatest.recording.dataset import LazySteps
from aatest.recording.temperatures import WATCH_NAME, logged_temperature

RECORDING = Path(__file__).parent / "data" / "streaming" / "recording.mcap"


def _counting(steps: LazySteps, reads: list[tuple[int, str]]) -> None:
    """Count every log (or piece stream) ``steps`` decodes from now on."""
    load, pieces = steps._load, steps._pieces
    assert pieces is not None

    def counted_load(index: int, source: str, channels: Any) -> Any:
        reads.append((index, source))
        return load(index, source, channels)

    def counted_pieces(index: int, source: str, channels: Any) -> Iterator[Any]:
        reads.append((index, source))
        return pieces(index, source, channels)

    steps._load, steps._pieces = counted_load, counted_pieces


@pytest.mark.parametrize("workers", ["1", "2"])
def test_summary_after_the_analysis_pass_decodes_nothing_and_equals_a_separate_read(
        workers: str, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("AATEST_WORKERS", workers)  # "2": tallies come back from forked workers
    data = read_dataset(RECORDING)
    done = run_analyses(data, ["sync"])
    assert "sync" in done.outputs
    steps = data.steps
    assert isinstance(steps, LazySteps)
    assert all(steps.watched(WATCH_NAME, i) for i in range(len(steps)))
    reads: list[tuple[int, str]] = []
    _counting(steps, reads)
    watched = logged_temperature(data)
    assert reads == []  # every step's tally came from the pass's decode

    alone = logged_temperature(read_dataset(RECORDING))  # no pass: each step read for it
    assert watched.samples == alone.samples > 0 and watched.source == alone.source
    assert (watched.min_c, watched.max_c) == (alone.min_c, alone.max_c)  # exact either way
    # the mean: the same samples' float sums grouped per step rather than per recorded block,
    # added exactly (fsum). The values are all positive (condition number 1), so a sum of n
    # of them in any order or SIMD/BLAS grouping errs by at most (n − 1)·eps relative: two
    # groupings differ by at most 2·n·eps (typically a few ulp)
    bound = 2 * watched.samples * np.finfo(float).eps
    assert watched.mean_c == pytest.approx(alone.mean_c, rel=bound)


def test_a_step_the_pass_did_not_decode_is_read_for_the_summary() -> None:
    data = read_dataset(RECORDING)
    from aatest.recording import temperatures

    temperatures.watch(data)  # registered, but no step decoded yet: every step read here
    steps = data.steps
    assert isinstance(steps, LazySteps)
    reads: list[tuple[int, str]] = []
    _counting(steps, reads)
    got = logged_temperature(data)
    assert sorted({i for i, _ in reads}) == list(range(len(steps)))
    assert got.samples > 0 and got == logged_temperature(read_dataset(RECORDING))
