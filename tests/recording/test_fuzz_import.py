"""Fuzzing the import directory (docs/interfaces.md §3) and the analysis behind it.

Structured mutations of the contract's example — a ``dataset.yaml`` value replaced by a hostile
scalar, a CSV cut to a few rows, a cell set to an extreme, a row repeated — are imported and,
when the import accepts them, analysed and summarised for the certificate exactly as
``aatest analyze`` does before rendering. The only allowed refusal is an aatest error (exit
1–3). The four crash sites the first fuzzing campaign found are regression cases below.
"""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from fuzzing import budget, refused_cleanly
from hypothesis import given
from hypothesis import strategies as st
from test_importer import MANIFEST, contract_columns, make_import_dir

from aatest.engine.analysis.passes import run_analyses
from aatest.engine.analysis.results_file import build_results, results_json
from aatest.engine.errors import AatestError, ImportDataError, ProblemsError
from aatest.engine.run.session import decide
from aatest.plugins.report.html import CalibrationCertificate
from aatest.recording.data.importer import import_dataset

#: an overflow (inf, NaN) inside the analyses is a defect even when the run ends cleanly: an
#: impossible value must be refused at import, naming its file, line and column
pytestmark = pytest.mark.filterwarnings("error::RuntimeWarning")

#: 400 samples at 2 kHz hold two cycles at 10 Hz (the contract's 5 Hz holds 399/400 of one)
BASE_MANIFEST = MANIFEST.replace("frequency_hz: 5.0", "frequency_hz: 10.0")
CERTIFICATE = CalibrationCertificate(CalibrationCertificate.Config(plots=False))

HOSTILE_SCALARS = ["1e+308", "-1e+308", "0", "-1", "1e-308", ".nan", ".inf", "-.inf",
                   "99999999999999999999999", "''", "[]", "{}", "null", "true", "x", "1e300",
                   "-273.16", "2.5", "1000000"]
MANIFEST_KEYS = ["sample_rate_hz", "frequency_hz", "accel_dps2", "inner_deg", "outer_deg",
                 "nominal_bias_v", "nominal_scale_v_per_dps2", "range_dps2", "axis", "kind"]
HOSTILE_CELLS = ["1e300", "-1e300", "1e308", "0", "nan", "inf", "", "x", "1e-300", "-0",
                 "99999999999999999999999"]


def analyse(directory: Path, out: Path) -> dict[str, Any]:
    """What ``aatest analyze DIR`` computes before rendering: results and the certificate view."""
    data = import_dataset(directory)
    analysis = run_analyses(data, list(data.metadata.get("analysis", [])))
    results = decide(build_results(data, analysis, 0.0, 0.0), data)
    doc = results_json(results)
    out.mkdir(parents=True, exist_ok=True)
    CERTIFICATE.context(results, out)
    return doc


def base_dir(root: Path) -> Path:
    return make_import_dir(root, *contract_columns(np.random.default_rng(11)), BASE_MANIFEST)


def replace_manifest_value(directory: Path, key: str, value: str) -> None:
    path = directory / "dataset.yaml"
    text = path.read_text()
    path.write_text(re.sub(rf"(\b{key}: )[^,}}\n]+", lambda m: m.group(1) + value, text, count=1))


def mutate_csv(path: Path, action: str, row: int, column: int, cell: str) -> None:
    lines = path.read_text().splitlines()
    header, rows = lines[0], lines[1:]
    row %= max(len(rows), 1)
    if action == "cut":
        rows = rows[:row]
    elif action == "cell" and rows:
        cells = rows[row].split(",")
        cells[column % len(cells)] = cell
        rows[row] = ",".join(cells)
    elif action == "repeat" and rows:
        rows.insert(row, rows[row])
    elif action == "drop_column":
        names = header.split(",")
        keep = [i for i in range(len(names)) if i != column % len(names)]
        header = ",".join(names[i] for i in keep)
        rows = [",".join(r.split(",")[i] for i in keep) for r in rows]
    path.write_text("\n".join([header, *rows]) + "\n")


def check(directory: Path, out: Path) -> None:
    try:
        analyse(directory, out)
    except AatestError as exc:
        assert refused_cleanly(exc), exc
        if isinstance(exc, ProblemsError):  # located: FILE:LINE:COLUMN
            assert all(p.line >= 1 and p.column >= 1 for p in exc.problems)


manifest_mutation = st.tuples(st.sampled_from(MANIFEST_KEYS), st.sampled_from(HOSTILE_SCALARS))
csv_mutation = st.tuples(st.sampled_from(["s01_table.csv", "s01_daq.csv"]),
                         st.sampled_from(["cut", "cell", "repeat", "drop_column"]),
                         st.integers(0, 700), st.integers(0, 6), st.sampled_from(HOSTILE_CELLS))


def _fuzz(root: Path, manifest: list[tuple[str, str]], csvs: list[tuple[Any, ...]]) -> None:
    directory = base_dir(root / "in")
    for key, value in manifest:
        replace_manifest_value(directory, key, value)
    for name, action, row, column, cell in csvs:
        mutate_csv(directory / name, action, row, column, cell)
    check(directory, root / "out")


@budget(12)
@given(manifest=st.lists(manifest_mutation, max_size=2),
       csvs=st.lists(csv_mutation, max_size=2))
def test_fuzz_import_and_analysis(tmp_path_factory: pytest.TempPathFactory,
                                  manifest: list[tuple[str, str]],
                                  csvs: list[tuple[Any, ...]]) -> None:
    _fuzz(tmp_path_factory.mktemp("fuzz"), manifest, csvs)


@pytest.mark.slow
@budget(12 * 20)
@given(manifest=st.lists(manifest_mutation, max_size=3),
       csvs=st.lists(csv_mutation, max_size=3))
def test_fuzz_import_and_analysis_long(tmp_path_factory: pytest.TempPathFactory,
                                       manifest: list[tuple[str, str]],
                                       csvs: list[tuple[Any, ...]]) -> None:
    _fuzz(tmp_path_factory.mktemp("fuzz"), manifest, csvs)


# -- the crash sites of the first campaign (each exited 4 before) ---------------------------


def test_contract_example_shorter_than_a_cycle_is_an_analysis_error(tmp_path: Path) -> None:
    directory = make_import_dir(tmp_path / "in", *contract_columns(np.random.default_rng(11)))
    doc = analyse(directory, tmp_path / "out")  # 399 samples at 5 Hz, 2 kHz: 399/400 of a cycle
    assert "holds no full cycle" in doc["analysis_errors"]["frf"]
    assert doc["overall"] != "pass"


def test_frequency_beyond_nyquist_is_located(tmp_path: Path) -> None:
    directory = base_dir(tmp_path)
    replace_manifest_value(directory, "frequency_hz", "1e+308")
    with pytest.raises(ProblemsError) as info:
        import_dataset(directory)
    (problem,) = info.value.problems
    assert (problem.line, problem.field) == (8, "steps.0.frequency_hz")
    assert "Nyquist" in problem.message


def test_one_row_daq_file_is_located(tmp_path: Path) -> None:
    directory = base_dir(tmp_path)
    mutate_csv(directory / "s01_daq.csv", "cut", 1, 0, "")
    with pytest.raises(ImportDataError, match=r"s01_daq.csv:2: 1 data row"):
        import_dataset(directory)


def test_impossible_temperature_is_located(tmp_path: Path) -> None:
    directory = base_dir(tmp_path)
    path = directory / "s01_daq.csv"
    lines = path.read_text().splitlines()
    lines = [lines[0] + ",temperature_c"] + [f"{r},{1e300 if i == 5 else 23.0}"
                                            for i, r in enumerate(lines[1:])]
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(ImportDataError, match=r"s01_daq.csv:7: temperature_c 1e\+300"):
        import_dataset(directory)


@pytest.mark.parametrize(("name", "column", "cell", "message"), [
    ("s01_table.csv", 1, "1e300", r"s01_table.csv:5: position_deg 1e\+300 ° is outside"),
    ("s01_table.csv", 2, "-1e300", r"s01_table.csv:5: rate_dps -1e\+300 °/s is outside"),
    ("s01_table.csv", 3, "1e308", r"s01_table.csv:5: accel_dps2 1e\+308 °/s² is outside"),
    ("s01_daq.csv", 3, "1e300", r"s01_daq.csv:5: v_sz 1e\+300 V is outside"),
])
def test_impossible_motion_and_volts_are_located(tmp_path: Path, name: str, column: int,
                                                 cell: str, message: str) -> None:
    """Each overflowed the reference comparison (× fs², squared) before it was refused."""
    directory = base_dir(tmp_path)
    mutate_csv(directory / name, "cell", 3, column, cell)  # data row 4, file line 5
    with pytest.raises(ImportDataError, match=message):
        import_dataset(directory)


def test_null_budget_contribution_leaves_shares_unstated() -> None:
    from aatest.plugins.report.stated import _budget
    from aatest.results import BudgetRow

    def row(contribution: float) -> BudgetRow:
        return BudgetRow(name="x", label="x", value=0.0, standard_uncertainty=contribution,
                         contribution=contribution)

    view = _budget("x", "dB", 1.0, 0.1, 2.0, [row(math.inf), row(0.1)])  # an overflow upstream
    assert [r["share_pct"] for r in view["rows"]] == [None, None]
    view = _budget("x", "dB", 1.0, 0.1, 2.0, [row(0.3), row(0.4)])
    # 0.09 / 0.25 and 0.16 / 0.25 of Σu², exact up to rounding of the float squares
    assert [r["share_pct"] for r in view["rows"]] == pytest.approx([36.0, 64.0], rel=1e-12)


# -- found by the long run (``-m slow``) -------------------------------------------------------


def test_frequency_too_low_for_a_finite_amplitude_is_located(tmp_path: Path) -> None:
    directory = base_dir(tmp_path)
    replace_manifest_value(directory, "frequency_hz", "1e-308")  # (2πf)² underflows to 0
    with pytest.raises(ProblemsError) as info:
        import_dataset(directory)
    (problem,) = info.value.problems
    assert problem.field == "steps.0.frequency_hz" and "no finite amplitude" in problem.message


def test_uncertainty_that_overflows_is_not_evaluated_and_says_why(tmp_path: Path) -> None:
    directory = base_dir(tmp_path)
    replace_manifest_value(directory, "accel_dps2", "1e-308")  # sensitivities ~1e308 overflow
    doc = analyse(directory, tmp_path / "out")
    assert "not evaluable" in doc["analysis_errors"]["uncertainty"]
    assert doc["overall"] != "pass"
