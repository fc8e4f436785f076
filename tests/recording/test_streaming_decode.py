"""Streaming decode: blocks are placed one at a time, partial decodes read only what is asked.

The codec rebuilds a log from any iterable of blocks (the reader hands it a generator), in any
order, and still refuses missing, repeated or misplaced blocks; a partial decode by name prefix
(every ``temperature*`` channel) returns only those channels, bit for bit.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from recording_data import sine_step, step_logs

from aatest.engine.logs import SampledLog
from aatest.recording import BLOCK_SAMPLES, RunRecorder, read_dataset
from aatest.recording.codec import blocks_to_log, encode_blocks
from aatest.recording.dataset import LazySteps, NamesStartingWith
from aatest.recording.proto import block_class

SAMPLES = 3 * BLOCK_SAMPLES + 17


def _blocks(log: SampledLog) -> list[Any]:
    count = -(-len(log) // BLOCK_SAMPLES)
    header = {"step_id": "s01", "source": log.source}
    return [block_class().FromString(b)
            for b in encode_blocks(log, header, BLOCK_SAMPLES, list(range(count)))]


def _daq() -> SampledLog:
    return step_logs(sine_step("s01", SAMPLES), seed=11)[1]


def _decode(blocks: Any, log: SampledLog, channels: Any = None) -> SampledLog:
    return blocks_to_log(blocks, log.source, log.sample_rate_hz, len(log),
                         dict(log.quantisation), channels)


def test_blocks_from_a_one_shot_generator_in_any_order_decode_bit_exact() -> None:
    log = _daq()
    blocks = _blocks(log)
    order = np.random.default_rng(2).permutation(len(blocks))
    taken: list[int] = []

    def one_at_a_time() -> Iterator[Any]:
        for k in order:
            taken.append(int(k))
            yield blocks[k]

    got = _decode(one_at_a_time(), log)
    assert taken == order.tolist()
    np.testing.assert_array_equal(got.time_s, log.time_s)
    for name, values in log.channels.items():
        assert got[name].dtype == values.dtype
        assert got[name].tobytes() == values.tobytes(), name


@pytest.mark.parametrize(("damage", "message"), [
    ("missing", "have gaps"), ("repeated", "is repeated"), ("shifted", "does not continue"),
    ("extra samples", "more samples than")])
def test_blocks_that_do_not_tile_the_record_are_refused(damage: str, message: str) -> None:
    log = _daq()
    blocks = _blocks(log)
    if damage == "missing":
        blocks = blocks[:1] + blocks[2:]
    elif damage == "repeated":
        blocks = [*blocks, blocks[1]]
    elif damage == "shifted":
        blocks[2].first_sample += 1
    else:
        blocks[-1].first_sample += 100
    with pytest.raises(ValueError, match=message):
        _decode(iter(blocks), log)


def _recorded_step(directory: Path, seed: int) -> tuple[LazySteps, SampledLog, SampledLog]:
    """One twin sine step written to a recording in ``directory`` and read back lazily; with
    the table and DAQ logs it was written from."""
    step = sine_step("s01", SAMPLES)
    table, daq = step_logs(step, seed=seed)
    recorder = RunRecorder(directory)
    recorder.write_step(step, table, daq)
    steps = read_dataset(recorder.finalize()).steps
    assert isinstance(steps, LazySteps)
    return steps, table, daq


def test_partial_decode_by_prefix_keeps_only_those_channels(tmp_path: Path) -> None:
    steps, _, daq = _recorded_step(tmp_path, seed=5)
    part = steps.partial(0, {"daq": NamesStartingWith("temp"), "table": NamesStartingWith("x")})
    assert set(part.daq.channels) == {"temperature_c"} and not part.table.channels
    assert part.daq["temperature_c"].tobytes() == daq["temperature_c"].tobytes()
    np.testing.assert_array_equal(part.daq.time_s, daq.time_s)
    assert "v_sz" not in NamesStartingWith("temp") and 3 not in NamesStartingWith("3")


@pytest.mark.pinned
def test_logged_temperature_summary_equals_the_whole_temperature_record() -> None:
    """The results' logged-temperature min/mean/max (what the certificate prints), accumulated
    step by step from partial decodes, is the summary of every temperature sample of the
    recording decoded whole."""
    from aatest.recording.temperatures import logged_temperature

    recording = Path(__file__).parent / "data" / "streaming" / "recording.mcap"
    every = np.concatenate([log[name] for s in read_dataset(recording).steps
                            for log in (s.daq, s.table) for name in log.channels
                            if name.startswith("temperature")])
    got = logged_temperature(read_dataset(recording))
    assert got.samples == every.size > 0 and got.source == str(recording)
    assert (got.min_c, got.max_c) == (every.min(), every.max())  # min and max are exact
    # the mean: per-piece float sums added exactly (fsum) against numpy's pairwise sum of the
    # whole; both err by a few ulp of sums of ~25 °C values, so 1e-12 relative holds anywhere
    assert got.mean_c == pytest.approx(every.mean(), rel=1e-12)


def test_pieces_of_a_recorded_log_are_its_blocks_in_order_and_concatenate_to_it(
        tmp_path: Path) -> None:
    steps, table, daq = _recorded_step(tmp_path, seed=6)
    pieces = list(steps.pieces(0, "daq", ["v_sz"]))
    assert [len(p) for p in pieces] == [BLOCK_SAMPLES] * (len(daq) // BLOCK_SAMPLES) + \
        ([len(daq) % BLOCK_SAMPLES] if len(daq) % BLOCK_SAMPLES else [])
    assert all(set(p.channels) == {"v_sz"} for p in pieces)
    joined = np.concatenate([p["v_sz"] for p in pieces])
    assert joined.tobytes() == daq["v_sz"].tobytes()
    assert np.concatenate([p.time_s for p in pieces]).tobytes() == daq.time_s.tobytes()
    whole = list(steps.pieces(0, "table"))
    assert len(whole) == -(-len(table) // BLOCK_SAMPLES)
    assert set(whole[0].channels) == set(table.channels)


def test_pieces_refuse_a_missing_block_when_they_reach_it() -> None:
    from aatest.recording.codec import blocks_to_pieces

    log = _daq()
    blocks = _blocks(log)
    pieces = blocks_to_pieces(iter(blocks[:2] + blocks[3:]), log.source, log.sample_rate_hz,
                              len(log), dict(log.quantisation))
    assert len(next(pieces)) == BLOCK_SAMPLES and len(next(pieces)) == BLOCK_SAMPLES
    with pytest.raises(ValueError, match="have gaps"):
        next(pieces)


def test_a_watch_rides_along_the_first_partial_decode_only(tmp_path: Path) -> None:
    """A registered watch is fed by the first partial decode of a step (the union of the
    channels, decoded once); the caller still gets only its channels, bit for bit."""
    from aatest.recording.dataset import StepWatch

    steps, _, daq = _recorded_step(tmp_path, seed=5)
    loads: list[tuple[int, str]] = []
    load = steps._load
    steps._load = lambda i, s, c: loads.append((i, s)) or load(i, s, c)  # type: ignore
    seen: list[set[str]] = []
    steps.watch("temp", StepWatch(channels=lambda p: {"daq": ["temperature_c"]},
                                  applies=lambda p: p.kind == "sine",
                                  reduce=lambda s: seen.append(set(s.daq.channels)) or
                                  float(s.daq["temperature_c"].sum())))
    with pytest.raises(KeyError):
        steps.watched("temp", 0)
    part = steps.partial(0, {"daq": ["sync_pulse"]})
    assert loads == [(0, "table"), (0, "daq")]
    assert seen == [{"sync_pulse", "temperature_c"}] and set(part.daq.channels) == {"sync_pulse"}
    assert part.daq["sync_pulse"].tobytes() == daq["sync_pulse"].tobytes()
    assert steps.watched("temp", 0) == float(daq["temperature_c"].sum())
    steps.partial(0, {"daq": ["sync_pulse"]})
    assert seen == [{"sync_pulse", "temperature_c"}]  # done once
