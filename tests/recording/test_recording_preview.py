"""The plottable preview: decoded generically (no aatest decoder), it matches the exact samples.

A viewer knows only MCAP and the FileDescriptorSet embedded in each schema; so do these tests:
the preview messages are decoded with ``mcap`` and protobuf's ``descriptor_pool`` +
``message_factory`` (Python) and with ``@mcap/core`` + protobufjs (TypeScript), and every
window's min, max and mean is compared with the samples aatest reads back from the blocks.
"""

from __future__ import annotations

import json
import shutil
import subprocess
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
import pytest
from google.protobuf import descriptor_pb2, descriptor_pool, message_factory
from mcap.reader import make_reader
from recording_data import run_meta, sine_step, step_logs

from aatest.engine.logs import SampledLog
from aatest.recording import RunRecorder, read_dataset

HERE = Path(__file__).parent
MCAP_TS = HERE.parent / "mcap_ts"
ARTEFACTS = HERE.parent.parent / "test-artifacts"
WINDOW = 400  # samples per 200 ms window at the test loggers' 2 kHz
#: a window's mean is a sum of WINDOW float64 values divided by WINDOW: summed in any order its
#: rounding is ≤ (WINDOW − 1)·eps·max|x| ≤ 2·WINDOW ulp of the largest magnitude (the reference
#: np.mean sums pairwise, aatest sequentially); both errors together stay under 4·WINDOW ulp
MEAN_ULPS = 4 * WINDOW


def _record(run_dir: Path, samples: int = 9001) -> RunRecorder:
    steps = [sine_step(f"s{i:02d}", samples) for i in (1, 2)]
    recorder = RunRecorder(run_dir)
    recorder.write_run_metadata(run_meta(steps))
    for seed, step in enumerate(steps):
        recorder.write_step(step, *step_logs(step, seed))
    recorder.finalize()
    return recorder


def _decode_generically(recording: Path) -> dict[str, dict[str, object]]:
    """Topic → {metadata, log_time_ns, fields}: what any protobuf-aware MCAP viewer sees."""
    topics: dict[str, dict[str, object]] = {}
    with open(recording, "rb") as stream:
        for schema, channel, message in make_reader(stream).iter_messages():
            if not channel.topic.startswith("/preview/"):
                continue
            pool = descriptor_pool.DescriptorPool()
            for file in descriptor_pb2.FileDescriptorSet.FromString(schema.data).file:
                pool.Add(file)
            kind = message_factory.GetMessageClass(pool.FindMessageTypeByName(schema.name))
            decoded = kind.FromString(message.data)
            topic = topics.setdefault(channel.topic, {"metadata": dict(channel.metadata),
                                                      "log_time_ns": [], "fields": {}})
            topic["log_time_ns"].append(message.log_time)  # type: ignore[attr-defined]
            for field in decoded.DESCRIPTOR.fields:
                topic["fields"].setdefault(  # type: ignore[attr-defined]
                    field.name, []).append(getattr(decoded, field.name))
    return topics


def _check_against_samples(topic: dict[str, object], logs: list[SampledLog],
                           channels: list[str]) -> None:
    """Every window's min/max equal the samples', the mean to rounding; times and units."""
    fields = {k: np.asarray(v) for k, v in topic["fields"].items()}  # type: ignore[attr-defined]
    units = json.loads(topic["metadata"]["units"])  # type: ignore[index]
    first = 0
    for log in logs:
        starts = np.arange(0, len(log), WINDOW)
        mine = slice(first, first + len(starts))
        first += len(starts)
        np.testing.assert_array_equal(fields["time_s"][mine], log.time_s[starts])
        for name in channels:
            data = np.asarray(log[name], dtype=np.float64)
            windows = [data[s:s + WINDOW] for s in starts]
            np.testing.assert_array_equal(fields[f"{name}_min"][mine], [w.min() for w in windows])
            np.testing.assert_array_equal(fields[f"{name}_max"][mine], [w.max() for w in windows])
            tol = MEAN_ULPS * np.spacing(np.abs(data).max())
            np.testing.assert_allclose(fields[f"{name}_mean"][mine],
                                       [w.mean() for w in windows], rtol=0, atol=tol)
            assert units[f"{name}_mean"] == log.units[name]
    assert first == len(fields["time_s"])


def _expected(run_dir: Path) -> tuple[list[SampledLog], list[SampledLog]]:
    steps = read_dataset(run_dir / "recording.mcap").steps
    return [s.table for s in steps], [s.daq for s in steps]


def test_python_protobuf_alone_decodes_the_preview_and_it_matches_the_samples(
        tmp_path: Path) -> None:
    _record(tmp_path)
    topics = _decode_generically(tmp_path / "recording.mcap")
    assert set(topics) == {"/preview/table", "/preview/daq"}
    tables, daqs = _expected(tmp_path)
    _check_against_samples(topics["/preview/table"], tables, [
        f"{a}_{q}" for a in ("inner", "outer") for q in ("position_deg", "rate_dps",
                                                         "accel_dps2")])
    _check_against_samples(topics["/preview/daq"], daqs, ["v_sz", "temperature_c"])
    # log times on the run's UTC time line: the first window at started_utc + the 5 s margin
    started = datetime.fromisoformat(str(run_meta([])["started_utc"]))
    times = topics["/preview/table"]["log_time_ns"]
    assert times[0] == round(started.timestamp()) * 10**9 + 5 * 10**9  # type: ignore[index]
    assert datetime.fromtimestamp(times[-1] / 1e9, UTC).year == 2026  # type: ignore[index]


def test_streamed_step_has_the_same_preview_as_a_one_shot_write(tmp_path: Path) -> None:
    """A DAQ log arriving in odd-sized chunks (windows split across them) previews the same."""
    step = sine_step("s01", 9001)
    table, daq = step_logs(step, 3)
    whole, streamed = tmp_path / "whole", tmp_path / "streamed"
    for run_dir in (whole, streamed):
        recorder = RunRecorder(run_dir)
        recorder.write_run_metadata(run_meta([step]))
        if run_dir is whole:
            recorder.write_step(step, table, daq)
        else:
            live = recorder.stream_step(step)
            for start in range(0, len(daq), 3333):
                stop = min(len(daq), start + 3333)
                live.add(SampledLog(daq.source, daq.sample_rate_hz, daq.time_s[start:stop],
                                    {k: v[start:stop] for k, v in daq.channels.items()},
                                    dict(daq.units), dict(daq.quantisation)))
            live.finish(table)
        recorder.finalize()
    one, two = (_decode_generically(d / "recording.mcap") for d in (whole, streamed))
    assert one == two
    assert not list((streamed / "steps").glob("*.preview"))


def test_preview_check_fails_on_a_changed_sample(tmp_path: Path) -> None:
    """The comparison can fail: one sample changed by 1e-6 °/s changes its window's max."""
    _record(tmp_path)
    topics = _decode_generically(tmp_path / "recording.mcap")
    tables, _ = _expected(tmp_path)
    log = tables[0]
    changed = dict(log.channels)
    changed["inner_rate_dps"] = changed["inner_rate_dps"].copy()
    changed["inner_rate_dps"][int(np.argmax(changed["inner_rate_dps"]))] += 1e-6
    bad = SampledLog(log.source, log.sample_rate_hz, log.time_s, changed, dict(log.units))
    with pytest.raises(AssertionError):
        _check_against_samples(topics["/preview/table"], [bad, tables[1]], ["inner_rate_dps"])


def test_typescript_reader_decodes_the_preview_and_a_browser_plots_it(tmp_path: Path) -> None:
    """``@mcap/core`` + protobufjs decode the same values; uPlot in headless Chromium plots
    them against UTC; the screenshot is kept in test-artifacts/ (the CI artefact)."""
    node = shutil.which("node")
    if node is None or not (MCAP_TS / "node_modules" / "uplot").is_dir():
        pytest.skip("needs node and `npm ci --prefix tests/mcap_ts` (done by .ci/run)")
    _record(tmp_path, samples=40_000)
    out, page = tmp_path / "preview.json", tmp_path / "preview.html"
    done = subprocess.run([node, str(MCAP_TS / "plot_preview.mjs"),
                           str(tmp_path / "recording.mcap"), str(out), str(page)],
                          capture_output=True, text=True, timeout=120, check=False)
    assert done.returncode == 0, done.stderr
    topics = json.loads(out.read_text())
    tables, daqs = _expected(tmp_path)
    for topic in topics.values():
        topic["log_time_ns"] = [int(t) for t in topic["log_time_ns"]]
    _check_against_samples(topics["/preview/table"], tables, ["inner_accel_dps2"])
    _check_against_samples(topics["/preview/daq"], daqs, ["v_sz", "temperature_c"])
    python = _decode_generically(tmp_path / "recording.mcap")
    assert topics["/preview/daq"]["log_time_ns"] == python["/preview/daq"]["log_time_ns"]
    chromium = shutil.which("chromium") or "/usr/bin/chromium"
    if not Path(chromium).exists():
        pytest.skip("needs Chromium for the screenshot")
    ARTEFACTS.mkdir(exist_ok=True)
    shot = ARTEFACTS / "recording-preview.png"
    shot.unlink(missing_ok=True)
    subprocess.run([chromium, "--headless", "--no-sandbox", "--disable-gpu",
                    f"--user-data-dir={tmp_path / 'chromium'}", "--window-size=1140,800",
                    f"--screenshot={shot}", page.as_uri()],
                   capture_output=True, timeout=120, check=False)
    assert shot.exists() and shot.stat().st_size > 10_000  # a plotted page, not a blank one


@pytest.mark.parametrize("samples", [8000, 9001, 150, 70_123])
def test_a_whole_log_previews_at_once_as_window_by_window(samples: int,
                                                          monkeypatch: pytest.MonkeyPatch) -> None:
    """``add(log, last=True)`` (a whole log, the short last window included in one pass) gives
    the bytes ``add`` then ``finish`` give: whole windows, a short last one, a log shorter
    than a window, and more windows than one chunk holds (chunks of 100 records here)."""
    from aatest.recording import preview
    from aatest.recording.preview import PreviewStream, records_per_chunk

    rng = np.random.default_rng(5)
    log = SampledLog("daq", 2000.0, np.arange(samples) / 2000.0,
                     {"v_sz": rng.normal(0, 1, samples), "temperature_c": np.full(samples, 23.5)},
                     {"v_sz": "V", "temperature_c": "°C"}, {})
    record_bytes = preview.layout_of(log).record_dtype().itemsize
    monkeypatch.setattr(preview, "CHUNK_BYTES", 100 * record_bytes)
    outputs = []
    for last in (False, True):
        records: list[bytes] = []
        stream = PreviewStream(3, 10**18, 10**18,
                               lambda _l, data, _t, into=records: into.append(data))
        stream.add(log, last=last)
        if not last:
            stream.finish()
        outputs.append(b"".join(records))
    assert outputs[0] == outputs[1]
    assert len(outputs[1]) == -(-samples // WINDOW) * record_bytes
    assert stream.layout is not None and records_per_chunk(stream.layout) == 100
    assert samples < 70_000 or -(-samples // WINDOW) > 100  # the longest spans chunks
