"""ISO/IEC 17025 §7.8 content of the certificate rendered from a shipped procedure on the twin.

One run of ``procedures/scale-factor.yaml`` through the CLI with a lab profile; each test checks
one §7.8 item on the rendered certificate against what the run recorded (results.json, the
recording, the procedure file, the twin's known lab temperature) — never against itself.
"""

from __future__ import annotations

import copy
import hashlib
import html
import json
import os
import re
import shutil
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from typer.testing import CliRunner

import aatest
from aatest.cli import app
from aatest.plugins.report.html import CalibrationCertificate
from aatest.recording.reader import read_dataset
from aatest.results import RunResults
from aatest.results.quantities import quantity
from aatest.twin.model import ChamberModel

PROCEDURE = Path(aatest.__file__).parent / "procedures" / "scale-factor.yaml"
LAB_YAML = """\
name: Example Calibration Lab
address: |
  Calibration Street 1
  12345 Example Town
accreditation:
  body: DAkkS
  number: D-K-12345-01-00
  scope: angular acceleration 0.1–10 Hz
signatories:
  - {name: Dr. Ada Example, function: Head of the calibration laboratory}
certificate_prefix: EXL
"""


@pytest.fixture(scope="module")
def certified(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, Any], str]:
    """(run dir, results.json, report text) of the shipped scale-factor procedure."""
    base = tmp_path_factory.mktemp("cert")
    lab = base / "lab.yaml"
    lab.write_text(LAB_YAML, encoding="utf-8")
    out = base / "run"
    result = CliRunner().invoke(app, [
        "run", str(PROCEDURE), "--out", str(out), "--no-progress", "--lab", str(lab),
        "--records", f"sqlite:///{base / 'records.db'}"])
    assert result.exit_code == 0, result.output
    results = json.loads((out / "results.json").read_text(encoding="utf-8"))
    return out, results, (out / "report.html").read_text(encoding="utf-8")


def _text(page: str) -> str:
    """The visible text of a page (tags, styles and SVG removed, entities decoded)."""
    page = re.sub(r"<(style|svg)\b.*?</\1>", " ", page, flags=re.S)
    return re.sub(r"\s+", " ", html.unescape(re.sub(r"<[^>]+>", " ", page)))


def _section(page: str, anchor: str) -> str:
    """Visible text from the heading with id ``anchor`` to the next h2."""
    start = page.index(f'<h2 id="{anchor}">')
    end = page.find("<h2", start + 4)
    return _text(page[start:end if end > 0 else None])


def test_title_and_lab_identity(certified: tuple[Path, dict[str, Any], str]) -> None:
    _, results, page = certified
    # the twin is simulated: the lab's layout, under the simulation's title and mark
    assert "<h1>Simulation report — not a calibration certificate</h1>" in page
    assert "Calibration certificate" not in _text(page)
    assert 'id="simulation-mark"' in page
    lab = _section(page, "lab")
    assert "Example Calibration Lab" in lab and "Calibration Street 1" in lab
    assert "DAkkS" in lab and "D-K-12345-01-00" in lab and "0.1–10 Hz" in lab
    assert results["metadata"]["lab"]["name"] == "Example Calibration Lab"  # signed with it


def test_unique_identification_on_every_page(certified: tuple[Path, dict[str, Any], str]
                                             ) -> None:
    _, results, page = certified
    number = results["certificate_number"]
    assert re.fullmatch(r"SIM-\d{4}-\d{6}", number)  # the simulation series, not the lab's EXL
    running = re.search(r'<div class="running-header"[^>]*>(.*?)</div>', page, re.S)
    assert running and number in running.group(1)
    # the running header is fixed in print, so Chromium repeats it on each printed page
    assert re.search(r"@media print \{[^}]*\.running-header \{[^}]*position: fixed", page)
    assert f'<meta name="aatest-certificate" content="{number}">' in page


def test_item_method_and_dates(certified: tuple[Path, dict[str, Any], str]) -> None:
    _, results, page = certified
    item = _section(page, "item")
    assert "sr207" in item and "A1234" in item
    method = _section(page, "method")
    assert "scale-factor" in method and "IEEE-671-style" in method
    text = PROCEDURE.read_text(encoding="utf-8")
    assert hashlib.sha256(text.encode()).hexdigest() in method
    dates = _section(page, "dates")
    assert results["metadata"]["started_utc"] in dates
    issued = re.search(r"date of issue \(UTC\) (\S+)", dates)
    assert issued and issued.group(1) >= results["metadata"]["started_utc"][:10]


def test_environment_is_the_logged_temperature(certified: tuple[Path, dict[str, Any], str]
                                               ) -> None:
    run_dir, _, page = certified
    logged = np.concatenate([s.daq["temperature_c"] for s in read_dataset(run_dir).steps])
    env = _section(page, "environment")
    found = re.search(r"min (\S+) °C, mean (\S+) °C, max (\S+) °C \((\d+) samples\)", env)
    assert found, env
    low, mean, high = (float(x) for x in found.groups()[:3])
    assert (low, mean, high) == pytest.approx(
        (logged.min(), logged.mean(), logged.max()), abs=0.006)
    assert int(found.group(4)) == logged.size
    assert mean == pytest.approx(ChamberModel().ambient_c, abs=0.5)  # the twin's lab


def _render(document: dict[str, Any], run_dir: Path) -> str:
    """The certificate of an edited results.json document."""
    report = CalibrationCertificate().render(RunResults.model_validate(document), run_dir, None)
    return report.read_text(encoding="utf-8")


def test_environment_comes_from_the_results_not_the_recording(
        certified: tuple[Path, dict[str, Any], str], tmp_path: Path) -> None:
    """Rendered into an empty directory (no recording to read), the certificate still states
    the logged temperatures: the analysis summarised them into the results."""
    _, results, page = certified
    env = _section(_render(copy.deepcopy(results), tmp_path), "environment")
    assert env == _section(page, "environment") and "samples" in env


@pytest.mark.parametrize("logged", [None, {"samples": 0, "source": "recording.mcap"}],
                         ids=["results-before-the-summary", "nothing-logged"])
def test_environment_not_recorded_without_logged_temperatures(
        certified: tuple[Path, dict[str, Any], str], tmp_path: Path,
        logged: dict[str, Any] | None) -> None:
    _, results, _ = certified
    doc = copy.deepcopy(results)
    doc["logged_temperature"] = logged
    page = _render(doc, tmp_path)
    assert "Temperature: not recorded" in _section(page, "environment")


def test_results_with_unit_u_k_and_probability(certified: tuple[Path, dict[str, Any], str]
                                                ) -> None:
    _, results, page = certified
    entry = results["analysis"]["scale_factor"]["v_sz"]
    row = re.search(r"<tr><td class=\"t\">v_sz</td><td class=\"t\">Scale factor</td>.*?</tr>",
                    page, re.S)
    assert row, "no scale-factor row in the results table"
    at = f"{entry['accel_dps2']:g} °/s², {entry['frequency_hz']:.4g} Hz"  # the level it is of
    assert at in row.group(0)
    cells = _text(row.group(0)).replace("Scale factor", "Scale_factor").replace(at, "").split()
    assert cells[1] == "Scale_factor"  # the quantity by its name, not its results.json key
    # printed to 6 significant digits (the quantity registry's rule): rel 5e-6 of rounding
    assert float(cells[2]) == pytest.approx(entry["scale_v_per_dps2"], rel=1e-5)
    assert cells[3] == "V/(°/s²)"
    assert float(cells[4]) == pytest.approx(entry["expanded_uncertainty"], rel=0.05)
    assert float(cells[5]) == pytest.approx(entry["coverage_factor"])
    assert float(cells[6]) == pytest.approx(100 * entry["coverage_probability"], abs=0.05)
    measurands = _text(page[page.index('<h3 id="measurands">'):])
    # the measurand the uncertainty stage defined for this very result, printed verbatim
    assert entry["measurand"] and " ".join(entry["measurand"].split()) in measurands


def test_measurand_stated_by_the_results_is_printed(
        certified: tuple[Path, dict[str, Any], str], tmp_path: Path) -> None:
    run_dir, results, _ = certified
    doc = copy.deepcopy(results)
    doc["analysis"]["scale_factor"]["v_sz"]["measurand"] = "the engine's own measurand text"
    page = _render(doc, run_dir)
    assert "the engine's own measurand text" in _text(page)


def test_traceability_statement(certified: tuple[Path, dict[str, Any], str]) -> None:
    run_dir, results, page = certified
    if not results["metadata"].get("traceability"):
        assert "Not stated" in _section(page, "traceability")
    doc = copy.deepcopy(results)
    doc["metadata"]["traceability"] = {"stated": True, "reference_temperature_c": 23.0,
                                       "instruments": {
        "encoder": {"cert_id": "ENC-2026-17", "cert_date": "2026-03-01", "lab": "PTB",
                    "accuracy": "±1″"},
        "logger": {"cert_id": "DAQ-2026-04", "cert_date": "2026-02-11", "lab": "not stated",
                   "accuracy": "gain ±0.1 %"}}}
    page = _render(doc, run_dir)
    trace = _section(page, "traceability")
    assert "ENC-2026-17" in trace and "DAQ-2026-04" in trace and "PTB" in trace
    assert "Not stated" not in trace


def test_conformity_statement_is_the_engines(certified: tuple[Path, dict[str, Any], str]
                                              ) -> None:
    _, results, page = certified
    conformity = _section(page, "conformity")
    rules = {v["rule"] for v in results["verdicts"]}
    assert all(f"'{r}'" in conformity for r in rules)
    assert f"overall {results['overall']}" in conformity
    for v in results["verdicts"]:  # each judged quantity by its name, with its verdict
        assert quantity(v["quantity"]).name in conformity and v["verdict"] in conformity
        assert v["quantity"] not in conformity


def test_adjustment_as_found_as_left(certified: tuple[Path, dict[str, Any], str]) -> None:
    run_dir, results, page = certified
    assert "No adjustment was made" in _section(page, "adjustment")
    doc = copy.deepcopy(results)
    doc["metadata"]["adjustment"] = {"made": True, "as_found": "0.004050 V/(°/s²)",
                                     "as_left": "0.004012 V/(°/s²)", "note": "gain trimmed"}
    page = _render(doc, run_dir)
    adjustment = _section(page, "adjustment")
    assert "0.004050" in adjustment and "0.004012" in adjustment and "gain trimmed" in adjustment


def test_signatory_name_and_function(certified: tuple[Path, dict[str, Any], str]) -> None:
    signatory = _section(certified[2], "signatory")
    assert "Dr. Ada Example" in signatory and "Head of the calibration laboratory" in signatory


def test_operator_prompts_and_unattended_mode(certified: tuple[Path, dict[str, Any], str]
                                              ) -> None:
    run_dir, results, page = certified
    assert "no operator prompts" in _section(page, "prompts")
    doc = copy.deepcopy(results)
    step = doc["steps"][0]["id"]
    doc["steps"][0]["prompt"] = "Mount the unit in its original orientation."
    doc["metadata"]["prompt_answers"] = [{"step_id": step, "answered_by": "j.doe",
                                          "answered_utc": "2026-11-23T10:00:00+00:00",
                                          "via": "auto"}]
    page = _render(doc, run_dir)
    prompts = _section(page, "prompts")
    assert "UNATTENDED" in prompts and "j.doe" in prompts and "2026-11-23T10:00:00" in prompts
    assert "original orientation" in prompts
    assert '<p class="fail" id="confirmation-mode">' in page  # shown prominently


def test_bad_lab_profile_names_file_line_and_field(tmp_path: Path) -> None:
    lab = tmp_path / "lab.yaml"
    lab.write_text("name: X\nsignatories:\n  - {name: A}\n", encoding="utf-8")
    result = CliRunner().invoke(app, ["validate", str(PROCEDURE)])  # the profile is read by run
    assert result.exit_code == 0
    result = CliRunner().invoke(app, ["run", str(PROCEDURE), "--out", str(tmp_path / "r"),
                                      "--lab", str(lab), "--no-progress"])
    assert result.exit_code == 2
    assert re.search(rf"{re.escape(str(lab))}:3:\d+: .*function", result.output), result.output
    assert not (tmp_path / "r" / "recording.mcap").exists()  # refused before the rig moved


@pytest.mark.browser
def test_pdf_pages_say_page_x_of_y_with_the_certificate_number(
        certified: tuple[Path, dict[str, Any], str], tmp_path: Path) -> None:
    """Printed in the real browser (Debian Chromium through Playwright); the first page is
    kept as a PNG (``AATEST_ARTEFACTS`` names a directory to copy it to)."""
    from aatest.plugins.report.pdf import find_browser, render_pdf

    browser = find_browser()
    if browser is None:
        pytest.skip("PDF test skipped: Debian chromium is not installed (apt-get install "
                    "chromium)")
    pypdf = pytest.importorskip("pypdf", reason="pypdf (test extra) reads the PDF's text")
    playwright = pytest.importorskip("playwright.sync_api",
                                     reason="playwright (test extra) drives the browser")
    run_dir, results, _ = certified
    pdf = render_pdf(run_dir / "report.html")
    pages = [p.extract_text() or "" for p in pypdf.PdfReader(str(pdf)).pages]
    assert len(pages) >= 2, "a certificate with its budgets spans several pages"
    number = results["certificate_number"]
    for i, text in enumerate(pages, start=1):
        assert f"page {i} of {len(pages)}" in text, text[-200:]
        assert number in text  # identification on every page (footer and running header)
        plain = " ".join(text.replace("\ufb01", "fi").split())  # Chromium sets the fi ligature
        assert "SIMULATION — not a calibration certificate" in plain  # the mark on every page

    shot = tmp_path / "certificate-page-1.png"
    with playwright.sync_playwright() as driver:
        chromium = driver.chromium.launch(executable_path=browser, args=["--no-sandbox"])
        page = chromium.new_page(viewport={"width": 900, "height": 1270})
        page.goto((run_dir / "report.html").resolve().as_uri())
        page.emulate_media(media="print")
        page.screenshot(path=str(shot))
        chromium.close()
    assert shot.stat().st_size > 20_000
    target = os.environ.get("AATEST_ARTEFACTS")
    if target:
        Path(target).mkdir(parents=True, exist_ok=True)
        shutil.copy2(shot, Path(target) / shot.name)
        shutil.copy2(pdf, Path(target) / "certificate.pdf")
