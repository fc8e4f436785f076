"""``export --tdms``/``--mf4`` piece by piece, read back bit for bit; the file's own time base;
value checks when a step is read; partial reads (docs/interfaces.md §3, "Logger files")."""

from __future__ import annotations

from collections.abc import Container, Iterator
from itertools import pairwise
from pathlib import Path

import numpy as np
import pytest
from logger_writers import assert_close_tree, mapping_yaml
from nptdms import ChannelObject, GroupObject, TdmsWriter
from recording_data import RATE_HZ, SENSOR, sine_step, step_logs
from ruamel.yaml import YAML

from aatest.engine.errors import ImportDataError
from aatest.engine.logs import SampledLog
from aatest.recording import read_dataset
from aatest.recording.data.logger_export import export_mf4, export_tdms
from aatest.recording.dataset import Dataset, LazySteps, _subset

#: pieces each log is cut into (as a streamed recording hands a long record over)
PIECES = 3


def _piece(log: SampledLog, part: slice) -> SampledLog:
    return SampledLog(log.source, log.sample_rate_hz, log.time_s[part],
                      {k: v[part] for k, v in log.channels.items()}, log.units)


def _pieced_dataset() -> tuple[Dataset, list[dict[str, SampledLog]]]:
    """Two synthetic steps (inner and outer axis) whose logs come in PIECES pieces."""
    steps = [sine_step("s01", samples=4096), sine_step("s02", samples=4096, axis="outer")]
    logs = [dict(zip(("table", "daq"), step_logs(step, seed), strict=True))
            for seed, step in enumerate(steps)]

    def load(index: int, source: str, channels: Container[str] | None) -> SampledLog:
        log = logs[index][source]
        return log if channels is None else _subset(log, channels)

    def pieces(index: int, source: str, channels: Container[str] | None
               ) -> Iterator[SampledLog]:
        whole = load(index, source, channels)
        edges = np.linspace(0, len(whole), PIECES + 1).astype(int)
        for a, b in pairwise(edges.tolist()):
            yield _piece(whole, slice(a, b))

    lazy = LazySteps(steps, load, [{s: len(v) for s, v in step.items()} for step in logs],
                     pieces)
    dataset = Dataset(procedure="pieces", sample_rate_hz=RATE_HZ, sensors=(SENSOR,),
                      steps=lazy, source=Path("."), metadata={"t_ref_c": 25.0})
    return dataset, logs


@pytest.mark.parametrize("export", [export_tdms, export_mf4])
def test_piecewise_export_reads_back_bit_for_bit(tmp_path: Path, export: object) -> None:
    dataset, logs = _pieced_dataset()
    out = export(dataset, tmp_path / "out")  # type: ignore[operator]
    again = read_dataset(out)
    assert [s.step for s in again.steps] == [s for s in dataset.planned]
    for mine, theirs in zip(logs, again.steps, strict=True):
        for source in ("table", "daq"):
            log, back = mine[source], getattr(theirs, source)
            np.testing.assert_array_equal(back.time_s, log.time_s)
            assert set(back.channels) == set(log.channels)
            for name, values in log.channels.items():
                np.testing.assert_array_equal(back[name], values, err_msg=name)
    assert again.metadata["fp_latch_s_present"] is True


def _waveform_tdms(tmp_path: Path, daq_time: str, sensor: np.ndarray | None = None,
                   table_time: np.ndarray | None = None) -> Path:
    """A TDMS file by npTDMS whose DAQ group states its time only as waveform properties."""
    step = sine_step("s01", samples=2048)
    table, daq = step_logs(step, 4)
    t0_s, dt_s = 0.125, 1 / RATE_HZ
    wf = {"wf_start_offset": t0_s, "wf_increment": dt_s}
    volts = daq["v_sz"] if sensor is None else sensor[: len(daq)]
    path = tmp_path / "logger.tdms"
    with TdmsWriter(str(path)) as writer:
        writer.write_segment([
            GroupObject("table"),
            ChannelObject("table", "t", table.time_s if table_time is None else table_time),
            *(ChannelObject("table", name, table[name])
              for name in ("inner_position_deg", "inner_rate_dps", "inner_accel_dps2")),
            ChannelObject("table", "fp", table["sync_pulse"]),
            GroupObject("daq"),
            ChannelObject("daq", "sync", daq["sync_pulse"], properties=wf),
            ChannelObject("daq", "trig", daq["trigger"], properties=wf),
            ChannelObject("daq", "v_sz", volts, properties=wf),
        ])
    manifest = {"procedure": "waveform", "sample_rate_hz": RATE_HZ,
                "sensors": [SENSOR.model_dump(mode="json")],
                "steps": [{"id": "s01", "kind": "sine", "axis": "inner",
                           "frequency_hz": step.frequency_hz, "accel_dps2": step.accel_dps2}]}
    table_map = {"time": {"channel": "t", "unit": "s"},
                 "position": {"channel": "inner_position_deg", "unit": "deg"},
                 "rate": {"channel": "inner_rate_dps", "unit": "deg/s"},
                 "accel": {"channel": "inner_accel_dps2", "unit": "deg/s^2"},
                 "freeze_pulse": {"channel": "fp"}}
    daq_map = {"freeze_pulse": {"channel": "sync"}, "trigger": {"channel": "trig"}}
    if daq_time:
        daq_map["time"] = {"channel": daq_time, "unit": "s"}
    text = mapping_yaml(manifest, "tdms", table_map, daq_map, [("table", "daq")],
                        file="logger.tdms")
    (tmp_path / "mapping.yaml").write_text(text, encoding="utf-8")
    return tmp_path / "mapping.yaml"


def test_a_tdms_waveform_gives_the_daq_time(tmp_path: Path) -> None:
    """No ``daq.time``: the samples are at wf_start_offset + k·wf_increment."""
    data = read_dataset(_waveform_tdms(tmp_path, daq_time=""))
    daq = data.steps[0].daq
    expected = 0.125 + np.arange(len(daq)) / RATE_HZ
    # npTDMS computes offset + k·increment itself: equal to a few ulp of the largest time
    np.testing.assert_allclose(daq.time_s, expected, rtol=0, atol=4 * np.spacing(expected[-1]))
    assert data.metadata["temperature_present"] is False
    assert (daq["temperature_c"] == 25.0).all()  # the stated T_ref fills the missing channel


def test_a_group_without_time_is_located(tmp_path: Path) -> None:
    """The table group has no waveform properties: without ``table.time`` it has no time."""
    mapping = _waveform_tdms(tmp_path, daq_time="")
    text = mapping.read_text().replace("  time:\n    channel: t\n    unit: s\n", "")
    mapping.write_text(text)
    with pytest.raises(ImportDataError) as caught:
        read_dataset(mapping)
    line = next(i for i, row in enumerate(text.splitlines(), 1) if row.startswith("table:"))
    assert f"{mapping}:{line}:1: table: group 'table'" in str(caught.value)
    assert "has no time base of its own" in str(caught.value)


def test_a_non_finite_sample_names_file_group_and_sample(tmp_path: Path) -> None:
    volts = np.full(4096, 2.5)
    volts[700] = np.nan
    data = read_dataset(_waveform_tdms(tmp_path, daq_time="", sensor=volts))
    with pytest.raises(ImportDataError, match=r"logger.tdms: group 'daq', channel 'v_sz': "
                       r"sample 700 is not a finite number"):
        _ = data.steps[0].daq


def test_time_that_does_not_increase_is_an_error(tmp_path: Path) -> None:
    table_time = np.arange(2048) / RATE_HZ
    table_time[1000] = table_time[999]
    data = read_dataset(_waveform_tdms(tmp_path, daq_time="", table_time=table_time))
    with pytest.raises(ImportDataError, match=r"group 'table': time does not increase at "
                       r"sample 1000"):
        _ = data.steps[0].table


def test_a_partial_read_returns_only_the_channels_asked_for(tmp_path: Path) -> None:
    dataset, logs = _pieced_dataset()
    again = read_dataset(export_tdms(dataset, tmp_path / "out"))
    assert isinstance(again.steps, LazySteps)
    step = again.steps.partial(1, {"table": {"inner_feedback_deg"}, "daq": {"sync_pulse"}})
    assert list(step.daq.channels) == ["sync_pulse"]
    assert list(step.table.channels) == ["inner_feedback_deg"]
    np.testing.assert_array_equal(step.table["inner_feedback_deg"],
                                  logs[1]["table"]["inner_feedback_deg"])


def test_an_unfinalised_mf4_file_is_refused(tmp_path: Path) -> None:
    dataset, _ = _pieced_dataset()
    out = export_mf4(dataset, tmp_path / "out")
    data_file = out / "recording.mf4"
    data_file.write_bytes(b"UnFinMF " + data_file.read_bytes()[8:])
    with pytest.raises(ImportDataError, match="unfinalised MDF file"):
        read_dataset(out)


def test_the_export_mapping_is_a_valid_mapping(tmp_path: Path) -> None:
    """The written mapping names the groups per step and marks the optional channels."""
    dataset, _ = _pieced_dataset()
    doc = YAML(typ="safe").load((export_tdms(dataset, tmp_path / "o") / "mapping.yaml")
                                .read_text())
    assert (doc["format"], doc["file"]) == ("tdms", "recording.tdms")
    assert [(s["table"], s["daq"]) for s in doc["steps"]] == [
        ("s01_table", "s01_daq"), ("s02_table", "s02_daq")]
    assert doc["table"]["accel"] == {"channel": "accel_dps2", "unit": "deg/s^2"}
    assert doc["table"]["channels"]["inner_position_deg"]["required"] is False


def test_diagnose_reads_a_tdms_export_like_the_csv_export(tmp_path: Path) -> None:
    """``aatest diagnose`` on the TDMS export finds what it finds on the CSV export: the same
    logs (bit for bit, see above) give the same diagnosis JSON and exit code."""
    import json

    from typer.testing import CliRunner

    from aatest.cli import app
    from aatest.recording.data.exporter import export_csv

    dataset, _ = _pieced_dataset()
    runs = {}
    for name, export in (("csv", export_csv), ("tdms", export_tdms)):
        out = export(dataset, tmp_path / name)
        done = CliRunner().invoke(app, ["diagnose", str(out), "--json",
                                        str(tmp_path / f"{name}.json")])
        assert done.exception is None or isinstance(done.exception, SystemExit), done.output
        runs[name] = (done.exit_code, json.loads((tmp_path / f"{name}.json").read_text()))
    assert runs["tdms"][0] == runs["csv"][0]
    # the logs are bit-identical (test above): only summation order may differ; the
    # tolerance and its reasoning are those of test_logger_files.RTOL
    assert assert_close_tree(runs["csv"][1], runs["tdms"][1], rtol=1e-9, atol=1e-12) > 10
    assert runs["csv"][0] in (0, 1) and runs["csv"][1]["baseline"]["rmse_v"] > 0


@pytest.mark.parametrize("export", [export_tdms, export_mf4, None])
def test_pieces_join_to_the_whole_log(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                      export: object) -> None:
    """A piecewise read (0.3 s = 600 samples a piece: 4096 = 6·600 + 496) joins to the whole
    read exactly, for the exports and for a TDMS waveform time base (``export`` None)."""
    from aatest.recording.data import logger_import

    monkeypatch.setattr(logger_import, "PIECE_S", 0.3)
    if export is None:
        data = read_dataset(_waveform_tdms(tmp_path, daq_time=""))
    else:
        data = read_dataset(export(_pieced_dataset()[0], tmp_path / "out"))  # type: ignore[operator]
    assert isinstance(data.steps, LazySteps)
    for source in ("table", "daq"):
        whole = getattr(data.steps[0], source)
        pieces = list(data.steps.pieces(0, source))
        assert [len(p) for p in pieces][:-1] == [600] * (len(pieces) - 1)
        assert sum(len(p) for p in pieces) == len(whole)
        np.testing.assert_array_equal(np.concatenate([p.time_s for p in pieces]), whole.time_s)
        for name, values in whole.channels.items():
            np.testing.assert_array_equal(np.concatenate([p[name] for p in pieces]), values,
                                          err_msg=name)
        one = list(data.steps.pieces(0, source, {"sync_pulse"}))
        assert all(list(p.channels) == ["sync_pulse"] for p in one)
