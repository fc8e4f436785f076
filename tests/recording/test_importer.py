"""Measured-data import (docs/interfaces.md §3): tolerant of layout, strict about content."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from aatest.engine.errors import ImportDataError, ProblemsError
from aatest.recording import read_dataset
from aatest.recording.data.importer import DatasetFileError, import_dataset

RATE_HZ = 2000.0
N = 400
FREQ_HZ = 5.0
ACCEL_DPS2 = 400.0

MANIFEST = """\
sensors:                      # one entry per sensor channel in the DAQ files
  - {channel: v_sz, axis: I, nominal_bias_v: 2.5, nominal_scale_v_per_dps2: 0.004014, range_dps2: 572.958}
sample_rate_hz: 2000
steps:
  - id: s01
    kind: sine
    axis: inner
    frequency_hz: 5.0
    accel_dps2: 400
    inner_deg: 0
    outer_deg: 0
    table: s01_table.csv
    daq: s01_daq.csv
"""  # noqa: E501 - the contract's example manifest, verbatim


def contract_columns(rng: np.random.Generator) -> tuple[dict, dict]:
    """Contract-only table and DAQ columns: 5 Hz, 400 °/s² sine; DAQ 0.1 s earlier, 20 ppm."""
    t = np.arange(N) / RATE_HZ
    w = 2 * math.pi * FREQ_HZ
    amp_deg = ACCEL_DPS2 / w**2
    table = {"time_s": t + 12.5, "position_deg": amp_deg * np.sin(w * t),
             "rate_dps": amp_deg * w * np.cos(w * t), "accel_dps2": -ACCEL_DPS2 * np.sin(w * t),
             "sync_pulse": ((np.arange(N) // 10) % 2 == 0).astype(int)}
    n_daq = N + 200
    t_daq = np.arange(n_daq) / (RATE_HZ * (1 + 20e-6))
    daq = {"time_s": t_daq, "sync_pulse": ((np.arange(n_daq) // 10) % 2 == 0).astype(int),
           "trigger": (np.arange(n_daq) >= 200).astype(int),
           "v_sz": 2.5 + rng.normal(0, 3e-3, n_daq)}
    return table, daq


def csv_text(columns: dict, newline: str = "\n") -> str:
    names = list(columns)
    rows = zip(*(np.asarray(columns[k]).astype(str) for k in names), strict=True)
    return newline.join([",".join(names), *(",".join(r) for r in rows)]) + newline


def make_import_dir(root: Path, table: dict, daq: dict, manifest: str = MANIFEST,
                    newline: str = "\n") -> Path:
    root.mkdir(parents=True, exist_ok=True)
    (root / "dataset.yaml").write_text(manifest)
    (root / "s01_table.csv").write_text(csv_text(table, newline), newline="")
    (root / "s01_daq.csv").write_text(csv_text(daq, newline), newline="")
    return root


@pytest.fixture
def columns() -> tuple[dict, dict]:
    return contract_columns(np.random.default_rng(11))


def test_contract_example_imports_as_a_dataset(tmp_path: Path, columns: tuple) -> None:
    table_cols, daq_cols = columns
    dataset = read_dataset(make_import_dir(tmp_path, table_cols, daq_cols))
    step = dataset.steps[0].step
    assert (step.kind, step.axis, step.samples, step.sample_rate_hz) == ("sine", "inner", N, 2000)
    assert step.duration_s == pytest.approx(N / RATE_HZ, rel=1e-12)
    assert step.amplitude_deg == pytest.approx(ACCEL_DPS2 / (2 * math.pi * FREQ_HZ) ** 2, rel=1e-12)
    table, daq = dataset.steps[0].table, dataset.steps[0].daq
    np.testing.assert_array_equal(table["inner_accel_dps2"], table_cols["accel_dps2"])
    np.testing.assert_array_equal(table.time_s, table_cols["time_s"])
    np.testing.assert_array_equal(daq["v_sz"], daq_cols["v_sz"])
    assert table["sync_pulse"].dtype == np.uint8 and daq["trigger"].dtype == np.uint8
    # the resting outer axis is filled from the step, NaN-free; no invented latch times
    np.testing.assert_array_equal(table["outer_position_deg"], np.zeros(N))
    assert np.all(np.isfinite(table["outer_accel_dps2"]))
    assert "fp_latch_s" not in table.channels
    np.testing.assert_array_equal(daq["temperature_c"], np.full(N + 200, 25.0))
    assert dataset.sensors[0].nominal_scale_v_per_dps2 == 0.004014
    meta = dataset.metadata
    assert meta["fp_latch_s_present"] is False and meta["temperature_present"] is False
    assert meta["columns_present"]["s01"]["table"][:3] == [
        "inner_position_deg", "inner_rate_dps", "inner_accel_dps2"]
    assert meta["t_ref_c"] == 25.0


def test_layout_tolerance(tmp_path: Path, columns: tuple) -> None:
    """CRLF, reordered and extra (text) columns, whitespace and a BOM give the same data."""
    table_cols, daq_cols = columns
    reference = import_dataset(make_import_dir(tmp_path / "a", table_cols, daq_cols))
    shuffled = {k: table_cols[k] for k in reversed(list(table_cols))}
    shuffled["operator_note"] = np.array(["ok"] * N)
    directory = make_import_dir(tmp_path / "b", shuffled, daq_cols, newline="\r\n")
    text = (directory / "s01_daq.csv").read_text()
    spaced = "\ufeff" + text.replace(",", " , ").replace("\n", "  \n", 1) + "\n\n"
    (directory / "s01_daq.csv").write_text(spaced, encoding="utf-8")
    dataset = import_dataset(directory)
    for mine, ref in zip(dataset.steps, reference.steps, strict=True):
        for log, ref_log in ((mine.table, ref.table), (mine.daq, ref.daq)):
            np.testing.assert_array_equal(log.time_s, ref_log.time_s)
            for name in ref_log.channels:
                np.testing.assert_array_equal(log[name], ref_log[name], err_msg=name)


def test_outer_axis_and_optional_columns(tmp_path: Path, columns: tuple) -> None:
    table_cols, daq_cols = columns
    table_cols = {**table_cols, "fp_latch_s": np.full(N, 1e-4),
                  "inner_position_deg": np.full(N, 90.0)}
    daq_cols = {**daq_cols, "temperature_c": np.full(N + 200, 40.0)}
    manifest = MANIFEST.replace("axis: inner", "axis: outer")
    manifest = manifest.replace("inner_deg: 0", "inner_deg: 90")
    dataset = import_dataset(make_import_dir(tmp_path, table_cols, daq_cols, manifest))
    table = dataset.steps[0].table
    np.testing.assert_array_equal(table["outer_accel_dps2"], table_cols["accel_dps2"])
    np.testing.assert_array_equal(table["inner_position_deg"], np.full(N, 90.0))
    np.testing.assert_array_equal(table["inner_accel_dps2"], np.zeros(N))
    np.testing.assert_array_equal(table["fp_latch_s"], table_cols["fp_latch_s"])
    assert dataset.metadata["fp_latch_s_present"] and dataset.metadata["temperature_present"]


def test_t_ref_from_model_file(tmp_path: Path, columns: tuple) -> None:
    directory = make_import_dir(tmp_path, *columns, MANIFEST + "model: model.yaml\n")
    (directory / "model.yaml").write_text("t_ref_c: 20.0\nsensors: []\n")
    dataset = import_dataset(directory)
    assert dataset.metadata["t_ref_c"] == 20.0
    np.testing.assert_array_equal(dataset.steps[0].daq["temperature_c"], 20.0)


def _damage(text: str, how: str) -> tuple[str, int]:  # noqa: PLR0911 - one return per damage kind
    """Return damaged CSV text and the 1-based line the error must name."""
    lines = text.split("\n")
    if how == "truncated_last_row":
        lines[-2] = lines[-2][: lines[-2].index(",") + 1].rstrip(",")
        return "\n".join(lines), len(lines) - 1
    if how == "non_numeric":
        cells = lines[7].split(",")
        cells[2] = "12.3abc"
        lines[7] = ",".join(cells)
        return "\n".join(lines), 8
    if how == "non_monotonic":
        lines[5], lines[6] = lines[6], lines[5]
        return "\n".join(lines), 7
    if how == "nan":
        cells = lines[3].split(",")
        cells[1] = "nan"
        lines[3] = ",".join(cells)
        return "\n".join(lines), 4
    if how == "missing_column":
        lines = [",".join(line.split(",")[:-1]) for line in lines]
        return "\n".join(lines), 1
    if how == "bad_sync":
        cells = lines[9].split(",")
        cells[4] = "0.5"
        lines[9] = ",".join(cells)
        return "\n".join(lines), 10
    return "", 1  # empty


@pytest.mark.parametrize(
    "how, message",
    [("truncated_last_row", "truncated"), ("non_numeric", "'12.3abc' is not a number"),
     ("non_monotonic", "does not increase"), ("nan", "not a finite number"),
     ("missing_column", "missing required column"), ("bad_sync", "must be 0 or 1"),
     ("empty", "empty file")],
    ids=lambda v: v if isinstance(v, str) and " " not in v else "",
)
def test_malformed_table_csv_names_file_and_line(
    tmp_path: Path, columns: tuple, how: str, message: str
) -> None:
    directory = make_import_dir(tmp_path, *columns)
    path = directory / "s01_table.csv"
    text, line = _damage(path.read_text(), how)
    path.write_text(text)
    with pytest.raises(ImportDataError, match=message) as info:
        import_dataset(directory)
    assert info.value.path == str(path)
    assert info.value.line == line
    assert str(info.value).startswith(f"{path}:{line}: ")


def test_manifest_errors_are_located(tmp_path: Path, columns: tuple) -> None:
    broken = MANIFEST.replace("frequency_hz: 5.0", "frequency_hz: fast").replace(
        "outer_deg: 0", "outer_deg: 0\n    colour: red")
    directory = make_import_dir(tmp_path, *columns, broken)
    with pytest.raises(DatasetFileError) as info:
        import_dataset(directory)
    assert isinstance(info.value, ProblemsError) and isinstance(info.value, ImportDataError)
    text = str(info.value)
    assert f"{directory / 'dataset.yaml'}:8:5: steps.0.frequency_hz:" in text
    assert f"{directory / 'dataset.yaml'}:12:5: steps.0.colour: Extra inputs" in text


def test_missing_csv_file_is_located_in_manifest(tmp_path: Path, columns: tuple) -> None:
    directory = make_import_dir(tmp_path, *columns)
    (directory / "s01_daq.csv").unlink()
    with pytest.raises(ImportDataError, match=r"dataset.yaml:13:5: steps.0.daq: file not found"):
        import_dataset(directory)


@pytest.mark.parametrize("daq_damage", ["missing", "malformed"])
def test_a_bad_table_file_is_reported_before_its_daq_file(
    tmp_path: Path, columns: tuple, daq_damage: str
) -> None:
    """The two files of a step are parsed side by side; the table file's error still comes
    first, as when they were read one after the other."""
    directory = make_import_dir(tmp_path, *columns)
    table = directory / "s01_table.csv"
    table.write_text(_damage(table.read_text(), "non_numeric")[0])
    daq = directory / "s01_daq.csv"
    if daq_damage == "missing":
        daq.unlink()
    else:
        daq.write_text(_damage(daq.read_text(), "non_numeric")[0])
    with pytest.raises(ImportDataError) as info:
        import_dataset(directory)
    assert info.value.path == str(table)


def two_step_dir(root: Path, columns: tuple) -> Path:
    """An import directory of two identical steps, ``s01`` and ``s02``."""
    step = MANIFEST[MANIFEST.index("  - id: s01"):]
    manifest = MANIFEST + step.replace("s01", "s02")
    directory = make_import_dir(root, *columns, manifest)
    for kind in ("table", "daq"):
        (directory / f"s02_{kind}.csv").write_bytes((directory / f"s01_{kind}.csv").read_bytes())
    return directory


@pytest.mark.parametrize("later_damage", ["malformed", "missing"])
def test_errors_keep_manifest_order_across_steps(
    tmp_path: Path, columns: tuple, later_damage: str
) -> None:
    """Files are parsed largest first, several at a time; the error reported is still the one
    a sequential read meets first: step 1's (small) DAQ file before step 2's larger table."""
    directory = two_step_dir(tmp_path, columns)
    daq = directory / "s01_daq.csv"
    daq.write_text(_damage(daq.read_text(), "non_numeric")[0])
    later = directory / "s02_table.csv"
    if later_damage == "missing":
        later.unlink()
    else:
        text, _ = _damage(later.read_text(), "non_numeric")
        later.write_text(text + text[text.index("\n") + 1:])  # twice the size, parsed first
    with pytest.raises(ImportDataError) as info:
        import_dataset(directory)
    assert (info.value.path, info.value.line) == (str(daq), 8)


def test_steps_keep_their_own_files(tmp_path: Path, columns: tuple) -> None:
    """Parsed out of order, each step still gets its own two files."""
    directory = two_step_dir(tmp_path, columns)
    table = directory / "s02_table.csv"
    table.write_text(table.read_text().replace("\n12.5,", "\n12.25,", 1))
    first, second = import_dataset(directory).steps
    assert (first.table.time_s[0], second.table.time_s[0]) == (12.5, 12.25)
    assert first.step.id == "s01" and second.step.id == "s02"


def test_sine_step_without_frequency_is_rejected(tmp_path: Path, columns: tuple) -> None:
    directory = make_import_dir(tmp_path, *columns, MANIFEST.replace("    frequency_hz: 5.0\n", ""))
    with pytest.raises(DatasetFileError, match="needs frequency_hz and accel_dps2"):
        import_dataset(directory)


def test_sensor_named_like_a_daq_column_is_rejected(tmp_path: Path, columns: tuple) -> None:
    manifest = MANIFEST.replace("channel: v_sz", "channel: trigger")
    directory = make_import_dir(tmp_path, *columns, manifest)
    with pytest.raises(DatasetFileError, match=r"dataset.yaml:2:6: sensors.0.channel: .*own"):
        import_dataset(directory)


@settings(max_examples=60, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    cut=st.integers(min_value=0, max_value=10_000),
    garbage=st.binary(max_size=40),
    which=st.sampled_from(["s01_table.csv", "s01_daq.csv", "dataset.yaml"]),
)
def test_random_truncation_and_garbage_only_raise_import_errors(
    tmp_path_factory: pytest.TempPathFactory, columns: tuple, cut: int, garbage: bytes, which: str
) -> None:
    directory = make_import_dir(tmp_path_factory.mktemp("fuzz"), *columns)
    path = directory / which
    data = path.read_bytes()
    cut = cut % (len(data) + 1)
    path.write_bytes(data[:cut] + garbage)
    try:
        dataset = import_dataset(directory)
    except ImportDataError:
        return
    # a survivable damage must still give consistent, finite logs
    for log in (dataset.steps[0].table, dataset.steps[0].daq):
        assert np.all(np.diff(log.time_s) > 0)
        assert all(np.all(np.isfinite(v)) for v in log.channels.values())


PARITY_CASES = {
    "plain": "time_s,a,note\n0,1.5,x\n0.5,2,y\n1,-0.0,z\n",
    "truncated": "time_s,a,note\n0,1.5,x\n0.5,2\n",
    "text_in_number": "time_s,a\n0,1.5\n0.5,1.2e\n",
    "inf": "time_s,a\n0,1.5\n0.5,inf\n",
    "not_increasing": "time_s,a\n0,1.5\n0,2\n",
    "missing": "time_s,b\n0,1\n",
    "empty_cell": "time_s,a\n0,\n1,2\n",
    "header_only": "time_s,a\n",
    "trailing_blank_lines": "time_s,a\n0,1\n1,2\n\n\n",
    "comment_and_crlf": "# c\r\ntime_s,a\r\n0,1\r\n\r\n1,2\r\n",
    "quoted_extra_text": 'time_s,a,note\n0,1,"p, q"\n1,2,r\n',
}


PARITY_CASES |= {
    "blank_line_inside": "time_s,a\n0,1\n\n1,2\n",
    "comment_inside": "time_s,a\n0,1\n# pause\n1,2\n",
    "padded_cells": "time_s,a\n0, 1.5 \n 1,2\n",
    "no_final_newline": "time_s,a\n0,1\n1,2",
}

# what the Arrow path must refuse (or read identically) although no Python pass looks at the
# rows: Arrow alone decides that a file is plain
PARITY_CASES |= {
    "comment_in_unparsed_first_column": "note,time_s,a\nx,0,1\n# c,0.5,2\ny,1,3\n",
    "whitespace_line": "time_s,a\n0,1\n   \n1,2\n",
    "crlf_rows_after_lf_header": "time_s,a\n0,1\r\n1,2\r\n",
    "cr_only": "time_s,a\r0,1\r1,2\r",
    "quoted_number": 'time_s,a\n0,"1"\n1,2\n',
    "quote_in_unparsed_text": 'time_s,a,note\n0,1,say "hi"\n1,2,r\n',
    "nul_in_unparsed_text": "time_s,a,note\n0,1,x\x00\n1,2,y\n",
    "nul_in_number": "time_s,a\n0,1\x00\n1,2\n",
    "plus_sign": "time_s,a\n0,+1.5\n1,2\n",
    "exponent_forms": "time_s,a\n0,1E3\n1,-2.5e-310\n2,1e+17\n",
    "overflow": "time_s,a\n0,1e999\n",
    "extra_field": "time_s,a\n0,1\n1,2,3\n",
    "header_then_blank": "time_s,a\n\n0,1\n",
    "finite_values_whose_sum_overflows": "time_s,a\n0,1.7e308\n1,1.7e308\n",
}
#: byte strings that are not UTF-8 (the tolerant path refuses them wherever they are)
PARITY_BYTES = {
    "latin1_in_unparsed_text": b"time_s,a,note\n0,1,caf\xe9\n1,2,y\n",
    "utf8_in_unparsed_text": "time_s,a,note\n0,1,caf\u00e9\n1,2,y\n".encode(),
}


def _parity_bytes(name: str) -> bytes:
    return PARITY_BYTES[name] if name in PARITY_BYTES else PARITY_CASES[name].encode()


@pytest.mark.parametrize("name", [*PARITY_CASES, *PARITY_BYTES],
                         ids=[*PARITY_CASES, *PARITY_BYTES])
def test_arrow_and_tolerant_csv_paths_agree(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, name: str
) -> None:
    """The Arrow fast path accepts and rejects exactly what the tolerant path does, with the
    same located messages and bit-identical values."""
    assert_paths_agree(tmp_path / "x.csv", _parity_bytes(name), monkeypatch)


def assert_paths_agree(path: Path, data: bytes, monkeypatch: pytest.MonkeyPatch) -> None:
    """Read ``data`` through both CSV paths; the outcomes must be identical."""
    from aatest.recording.data import csv_table

    path.write_bytes(data)

    def outcome() -> object:
        try:
            got = csv_table.read_csv(path, ["time_s", "a"])
        except ImportDataError as exc:
            return str(exc)
        return ({k: v.view(np.uint64).tolist() for k, v in got.columns.items()},
                got.header, got.row_lines.tolist())

    with monkeypatch.context() as patch:
        fast = outcome()
        patch.setattr(csv_table, "_read_plain", lambda *args: None)
        assert fast == outcome()


_CELLS = st.sampled_from(["0", "1", "-0.0", "1.5", "2e-3", " 1", "1 ", "+1", "x", "", "nan",
                          '"1"', "# c", "1e999", "\x00", "caf\u00e9"])
_LINE_ENDS = st.sampled_from(["\n", "\r\n", "\r"])


@settings(max_examples=150, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    header=st.sampled_from(["time_s,a", "time_s,a,note", "note,time_s,a", "a,time_s"]),
    rows=st.lists(st.lists(_CELLS, min_size=1, max_size=4), min_size=0, max_size=5),
    ends=st.lists(_LINE_ENDS, min_size=6, max_size=6),
    final_end=st.booleans(),
)
def test_paths_agree_on_generated_csv(
    tmp_path_factory: pytest.TempPathFactory, monkeypatch: pytest.MonkeyPatch, header: str,
    rows: list[list[str]], ends: list[str], final_end: bool,
) -> None:
    """Generated near-plain files (odd cells, field counts and line ends): the two paths agree."""
    lines = [header, *(",".join(row) for row in rows)]
    text = "".join(line + end for line, end in zip(lines, ends, strict=False))
    if not final_end:
        text = text.rstrip("\r\n")
    path = tmp_path_factory.mktemp("parity") / "x.csv"
    assert_paths_agree(path, text.encode(), monkeypatch)


def test_plain_csv_takes_the_arrow_path(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from aatest.recording.data import csv_table

    path = tmp_path / "x.csv"
    path.write_text(PARITY_CASES["plain"])
    monkeypatch.setattr(csv_table, "_split_lines", lambda p: pytest.fail("tolerant path taken"))
    got = csv_table.read_csv(path, ["time_s", "a"])
    assert got.row_lines.tolist() == [2, 3, 4]
    assert got.columns["a"].view(np.uint64).tolist() == np.array([1.5, 2.0, -0.0]).view(
        np.uint64).tolist()


def test_plain_numeric_csv_is_never_copied_into_python(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A file of wanted numeric columns only is parsed by Arrow from the file itself: no Python
    copy of its text, no scan of it (the reason import is fast), yet located errors remain."""
    from aatest.recording.data import csv_table

    path = tmp_path / "x.csv"
    path.write_text("time_s,a\n0,1.5\n0.5,2\n")
    with monkeypatch.context() as patch:
        patch.setattr(Path, "read_bytes", lambda self: pytest.fail(f"{self} read into Python"))
        got = csv_table.read_csv(path, ["time_s", "a"])
    assert got.columns["a"].tolist() == [1.5, 2.0]
    path.write_text("time_s,a\n0,1.5\n0.5,2x\n")
    with pytest.raises(ImportDataError, match=r"x\.csv:3: column 'a': '2x' is not a number"):
        csv_table.read_csv(path, ["time_s", "a"])
