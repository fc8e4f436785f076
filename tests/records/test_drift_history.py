"""A unit whose sensor ages: five twin calibrations, half a year apart, with a growing scale factor.

Each calibration uses its own rig model file (``daq: {plugin: sim, model: FILE}``) with a larger
``scale_v_per_dps2``; the recording's start time is set per calibration so the drift is per
year. ``history`` must recover the aging rate, and ``--html`` must render the trend plot.
"""

from __future__ import annotations

import json
import re
import shutil
import subprocess
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
import pytest
from matplotlib.image import imread
from typer.testing import CliRunner

from aatest.cli import app

PROCEDURE = Path(__file__).parents[2] / "src" / "aatest" / "procedures" / "scale-factor.yaml"
NOMINAL_V_PER_DPS2 = 0.004014
AGING_PER_YEAR = 0.004  # +0.4 % of nominal per year
STARTS = [datetime(2024, 1, 15, 9, 0, tzinfo=UTC),
          datetime(2024, 7, 15, 9, 0, tzinfo=UTC),
          datetime(2025, 1, 15, 9, 0, tzinfo=UTC),
          datetime(2025, 7, 15, 9, 0, tzinfo=UTC),
          datetime(2026, 1, 15, 9, 0, tzinfo=UTC)]


def _scale_at(moment: datetime) -> float:
    years = (moment - STARTS[0]).total_seconds() / (365.25 * 86400)
    return NOMINAL_V_PER_DPS2 * (1 + AGING_PER_YEAR * years)


def _rig_file(folder: Path, index: int, scale: float) -> Path:
    model = folder / f"aged-{index}.yaml"
    model.write_text(f"sensors:\n  - {{channel: v_sz, axis: I, scale_v_per_dps2: {scale!r}}}\n")
    rig = folder / f"rig-{index}.yaml"
    rig.write_text(f"turntable: {{plugin: sim}}\ndaq: {{plugin: sim, model: {model}}}\n"
                   "chamber: {plugin: none}\n")
    return rig


def _at(moment: datetime) -> type[datetime]:
    class _Clock(datetime):
        @classmethod
        def now(cls, tz: object = None) -> datetime:  # type: ignore[override]
            return moment

    return _Clock


@pytest.fixture(scope="module")
def aged_unit(tmp_path_factory: pytest.TempPathFactory) -> str:
    """Five registered calibrations of A1234, made once for the module (five runs); returns the
    records URL. The tests only read the store."""
    from aatest.engine.run import runner

    folder = tmp_path_factory.mktemp("aged")
    url = f"sqlite:///{folder / 'records.sqlite'}"
    with pytest.MonkeyPatch.context() as monkeypatch:
        for index, start in enumerate(STARTS):
            monkeypatch.setattr(runner, "datetime", _at(start))
            rig = _rig_file(folder, index, _scale_at(start))
            result = CliRunner().invoke(app, [
                "run", str(PROCEDURE), "--rig", str(rig), "--out", str(folder / f"cal{index}"),
                "--seed", str(index + 1), "--no-progress", "--records", url])
            assert result.exit_code == 0, result.output
    return url


def test_history_recovers_the_aging_rate(aged_unit: str) -> None:
    from aatest.records.history import fit_drift
    from aatest.records.store import RecordStore

    with RecordStore.open(aged_unit) as store:
        assert store.history("A1234") == []  # twin runs are simulations: kept apart
        records = store.history("A1234", include_simulations=True)
    assert [r.calibrated_utc for r in records] == STARTS
    drift = fit_drift(records, "scale_factor.v_sz")
    assert drift is not None and drift.u_per_year is not None and drift.points == 5
    true_per_year = NOMINAL_V_PER_DPS2 * AGING_PER_YEAR
    # the twin's calibration reads ≈0.06 % low at every age, so the slope scales the same way
    assert drift.per_year == pytest.approx(true_per_year, rel=0.01)
    assert abs(drift.per_year - true_per_year) <= max(3 * drift.u_per_year, 0.01 * true_per_year)
    assert drift.per_year > 10 * drift.u_per_year, "the aging must be resolved, not noise"
    result = CliRunner().invoke(app, ["history", "A1234", "--records", aged_unit,
                                      "--include-simulations"])
    assert result.exit_code == 0
    match = re.search(r"drift of Scale factor v_sz: \+([0-9.e-]+) V/\(°/s²\) per year",
                      result.stdout)
    assert "scale_factor" not in result.stdout  # quantities by name, not by field
    assert "Scale factor v_sz ± U [V/(°/s²)]" in result.stdout
    header, rule, *rows = result.stdout.split("\n\n")[1].splitlines()
    assert len(rows) == len(STARTS) and set(rule.strip()) == {"─"}
    # every cell of the rows sits under its heading (rich aligns the columns)
    column = header.index("Verdict")
    assert all(row[column:].split()[0] in ("pass", "fail", "conditional-pass") for row in rows)
    # U with two significant digits (GUM 7.2.6), never the raw float
    assert all(re.search(r"± \d\.\de-\d\d", row) for row in rows)
    assert match and float(match.group(1)) == pytest.approx(true_per_year, rel=0.01)
    assert "next due:" not in result.stdout  # simulations never set a due date


def test_history_html_renders_the_trend_plot(aged_unit: str, tmp_path: Path) -> None:
    page = tmp_path / "trend" / "A1234.html"
    result = CliRunner().invoke(app, ["history", "A1234", "--records", aged_unit,
                                      "--html", str(page), "--json", "--include-simulations"])
    assert result.exit_code == 0, result.output
    assert len(json.loads(result.stdout)["records"]) == 5
    html = page.read_text(encoding="utf-8")
    assert 'id="trend-scale_factor.v_sz"' in html and html.count("<svg") == 1
    assert html.count('class="certificate"') == 5 and "datasheet limits" in html
    assert 'id="next-due">—' in html  # simulations only: no due date
    browser = "/usr/bin/chromium" if Path("/usr/bin/chromium").exists() else shutil.which(
        "chromium")
    if not browser:
        pytest.skip("trend-plot screenshot skipped: Debian chromium is not installed")
    shot = tmp_path / "trend.png"
    subprocess.run([browser, "--headless", "--no-sandbox", "--disable-gpu", "--no-first-run",
                    "--disable-background-networking", "--disable-component-update",
                    f"--user-data-dir={tmp_path / 'profile'}", f"--screenshot={shot}",
                    "--window-size=1000,900", page.resolve().as_uri()],
                   check=True, capture_output=True, timeout=120)
    image = imread(shot)[..., :3]
    c0 = np.array([0x1F, 0x77, 0xB4]) / 255.0  # matplotlib's C0: the calibration markers
    markers = np.all(np.abs(image.reshape(-1, 3) - c0) < 0.08, axis=1).sum()
    red = np.all(np.abs(image.reshape(-1, 3) - np.array([0xD6, 0x27, 0x28]) / 255.0) < 0.08,
                 axis=1).sum()  # tab:red, the datasheet limits
    assert markers > 100, "no calibration points drawn"
    assert red > 50, "no datasheet limit lines drawn"
