"""The four report plugins render self-contained, escaped, gracefully degrading HTML."""

from __future__ import annotations

import hashlib
import math
import re
from pathlib import Path

import pytest
from contract_results import decided, make_results

from aatest.bundle.signing import (
    generate_keypair,
    key_fingerprint,
    load_private_key,
    public_key_path,
    sign_bundle,
    trusted_public_key,
    verify_bundle,
)
from aatest.engine import registry
from aatest.engine.analysis.results_file import write_results
from aatest.plugins.report.html import (
    CalibrationCertificate,
    DiagnosisReport,
    FrequencyResponseReport,
    MisalignmentReport,
)
from aatest.results import RunResults
from aatest.results.frf import FrfResult
from aatest.results.root import Signature
from aatest.results.transfer_function import TransferFunctionResult

FAST = CalibrationCertificate(CalibrationCertificate.Config(plots=False))
REPORTS = ["calibration-certificate", "frequency-response", "misalignment", "diagnosis"]
DIAGNOSIS = {
    "baseline": {"rmse_v": 0.0123},
    "findings": [{"effect": "bias_temperature", "parameters": {"coefficient_v_per_c": 0.00041},
                  "ci95": {"coefficient_v_per_c": [0.00038, 0.00044]},
                  "evidence": {"delta_bic": -4521.0, "rmse_v_before": 0.0123,
                               "rmse_v_after": 0.00102}}],
    "gain": {"rmse_v_before": 0.0123, "rmse_v_after": 0.00102, "reduction_pct": 91.7},
    "residuals": {"v_sz": {"per_step": [{"step": "s001", "kind": "sine", "rms_v_nominal": 0.077,
                                         "rms_v_extended": 0.0157}],
                           "spectrum_lines": [{"step": "s001", "frequency_hz": 33.16,
                                               "amplitude_v": 0.0057, "class": "unrelated"}]}},
    "candidates": [{"effect": "g_sensitivity", "delta_bic": None, "accepted": False,
                    "testable": False, "reason": "gravity spans 0.00 g"},
                   {"effect": "time_delay", "delta_bic": 3.1, "accepted": False},
                   {"effect": "bias_temperature", "delta_bic": -4521.0, "accepted": True}],
}


def _visible_text(html: str) -> str:
    html = re.sub(r"<(svg|style).*?</\1>", " ", html, flags=re.S)
    return re.sub(r"\s+", " ", re.sub(r"<[^>]+>", " ", html))


@pytest.mark.parametrize("name", REPORTS, ids=REPORTS)
def test_entry_points_load_and_validate(name: str) -> None:
    info = registry.load("report", name)
    config = registry.configure(info, {})
    assert info.target(config) is not None
    with pytest.raises(Exception, match="bad options"):
        registry.configure(info, {"colour": "red"})


def test_certificate_has_every_section_and_plot(results: RunResults, run_dir: Path) -> None:
    results.signature = Signature(fingerprint="ab" * 32)
    path = CalibrationCertificate(CalibrationCertificate.Config()).render(results, run_dir, None)
    assert path == run_dir / "report.html"
    html = path.read_text()
    text = _visible_text(html)
    for heading in ("Scale factor", "Bias and g-sensitivity", "Temperature coefficients",
                    "Misalignment (pivoted method)", "Frequency response", "Transfer function",
                    "Uncertainty budgets", "Traceability", "Result against the datasheet"):
        assert heading in text, heading
    # own plots (3 curves, 3 Bode, 3 bias-vs-T, 1 complex plane) + the analysis' PSD figure
    assert html.count("<svg") == 11
    assert 'content="' + "ab" * 32 in html and "ab" * 32 in text
    assert "http://" not in re.sub(r'xmlns(:\w+)?="[^"]+"|<svg.*?</svg>', "", html, flags=re.S)
    recording = hashlib.sha256((run_dir / "recording.mcap").read_bytes()).hexdigest()
    assert recording in text and "3f" * 32 in text
    assert "A. Tester &lt;script&gt;x&lt;/script&gt;" in html and "<script>" not in html
    assert "0.00401400 ± 5.6e-06" in text  # K with U (k = 2; logger gain 0.1 % dominates)
    assert "22.4 °C; chamber set-points 22.0, -21.0, 48.0 °C" in text


def test_sections_degrade_when_keys_are_absent(results: RunResults, run_dir: Path) -> None:
    a = results.analysis
    a.frf = a.transfer_function = a.misalignment = a.temperature = a.noise = a.sync = None
    results.figures = {}
    entry = results.analysis.scale_factor["v_sz"]  # some values not estimated
    entry.nonlinearity_dps2, entry.ci95 = math.nan, []
    text = _visible_text(FAST.render(results, run_dir, None).read_text())
    assert "Scale factor" in text and "Frequency response" not in text
    assert "Misalignment (pivoted method)" not in text and "Unsigned report." in text
    bare = RunResults(procedure="empty")
    for cls in (CalibrationCertificate, FrequencyResponseReport, MisalignmentReport):
        html = cls(cls.Config(plots=False)).render(bare, run_dir, None).read_text()
        assert "Traceability" in _visible_text(html)


def test_verdict_fails_outside_datasheet(run_dir: Path) -> None:
    """The certificate shows the engine's verdict: 12.3 mV off nominal, limit ±10 mV."""
    raw = make_results()
    raw["analysis"]["bias"]["v_sz"]["bias_v"] = 2.5123
    results = decided(raw)
    html = FAST.render(results, run_dir, None).read_text()
    row = re.search(r"<tr><td class=\"t\">Bias deviation from nominal</td>"
                    r"<td class=\"t\">v_sz</td>.*?</tr>", html, re.S)
    assert row and 'class="fail"' in row.group(0) and "0.0123" in row.group(0)
    assert results.overall == "fail" and 'class="fail">fail</strong>' in html


def test_report_never_decides(results: RunResults, run_dir: Path) -> None:
    """A value changed after the engine decided leaves the verdict as decided; results
    without the engine's verdicts show no verdict (``aatest report`` refuses them)."""
    results.analysis.bias["v_sz"].bias_v = 2.6
    html = FAST.render(results, run_dir, None).read_text()
    row = re.search(r"<tr><td class=\"t\">Bias deviation from nominal</td>"
                    r"<td class=\"t\">v_sz</td>.*?</tr>", html, re.S)
    assert row and 'class="pass"' in row.group(0)
    results.verdicts, results.overall = [], "none"
    text = _visible_text(FAST.render(results, run_dir, None).read_text())
    assert "No conformity statement" in text and "Bias deviation" not in text


def test_certificate_names_reference_rule_and_budgets(results: RunResults,
                                                      run_dir: Path) -> None:
    text = _visible_text(FAST.render(results, run_dir, None).read_text())
    assert "Decision rule: simple" in text and f"Overall verdict: {results.overall}" in text
    assert "smoothed position" in text  # the scale factor's acceleration reference
    assert "reference: encoder accuracy rectangular" in text  # a budget row from the results


def test_tampered_figure_is_withheld(results: RunResults, run_dir: Path) -> None:
    results.figures["noise"]["psd"] = (
        '<svg xmlns="http://www.w3.org/2000/svg" onload="alert(1)"/>')
    html = FAST.render(results, run_dir, None).read_text()
    assert "alert(1)" not in html and "figure withheld: event attribute onload" in html


@pytest.mark.parametrize("cls", [FrequencyResponseReport, MisalignmentReport],
                         ids=["frequency-response", "misalignment"])
def test_focused_reports(cls: type, results: RunResults, run_dir: Path) -> None:
    text = _visible_text(cls(cls.Config(plots=False)).render(results, run_dir, None).read_text())
    assert ("Frequency response" in text) == (cls is FrequencyResponseReport)
    assert ("Misalignment (pivoted method)" in text) == (cls is MisalignmentReport)
    assert "Traceability" in text


def test_diagnosis_report(run_dir: Path) -> None:
    results = {**DIAGNOSIS, "figures": {"diagnose": {"residual_vs_temperature":
               '<svg xmlns="http://www.w3.org/2000/svg"><path d="M0 0L5 5"/></svg>'}}}
    path = DiagnosisReport().render(results, run_dir, None)
    assert path == run_dir / "diagnosis.html"
    text = _visible_text(path.read_text())
    assert "bias_temperature coefficient_v_per_c 4.100e-04 [3.800e-04, 4.400e-04]" in text
    assert text.index("bias_temperature -4521.0") < text.index("time_delay 3.100")  # ranked
    assert "3 g_sensitivity — no not testable: gravity spans 0.00 g" in text  # last
    assert "s001 sine 0.0770 0.0157" in text and "33.16 0.00570 unrelated" in text
    assert "91.7" in text and path.read_text().count("<svg") == 3


def test_signed_certificate_round_trip(results: RunResults, run_dir: Path,
                                       tmp_path: Path) -> None:
    """Runner flow: fingerprint into results, render, write results, sign; then tamper."""
    key = tmp_path / "lab.key"
    generate_keypair(key)
    private = load_private_key(key)
    results.signature = Signature(fingerprint=key_fingerprint(private))
    write_results(results, run_dir)
    report = FAST.render(results, run_dir, None)
    sign_bundle(report, private)
    trusted = [trusted_public_key(public_key_path(key))]
    assert verify_bundle(report, trusted).ok
    results.analysis.bias["v_sz"].bias_v = 2.4
    FAST.render(results, run_dir, None)
    assert verify_bundle(report, trusted).reasons == [
        "report.html: modified (sha256 differs from the signed value)"]


def test_own_plot_only_where_the_analysis_gave_none(results: RunResults, run_dir: Path) -> None:
    a = results.analysis
    a.scale_factor = a.bias = a.temperature = a.misalignment = a.noise = None
    a.frf = FrfResult({"v_sz": a.frf["v_sz"]})
    a.transfer_function = TransferFunctionResult({"v_sz": a.transfer_function["v_sz"]})
    results.metadata.sensors = results.metadata.sensors[:1]
    results.figures = {"frf": {"bode_v_sz": '<svg xmlns="http://www.w3.org/2000/svg"/>'}}
    html = FrequencyResponseReport().render(results, run_dir, None).read_text()
    assert "Frequency response: bode v sz" in html and "Bode v_sz" not in html
    results.figures = {}
    html = FrequencyResponseReport().render(results, run_dir, None).read_text()
    assert "Bode v_sz" in html


def test_diagnosis_report_names_the_steps_it_left_out(run_dir: Path) -> None:
    """Steps the logger clipped and steps that could not be synchronised are listed with why,
    so a reader knows the diagnosis did not see them."""
    document = {**DIAGNOSIS, "steps_clipped": {"f1-a400": {"v_sz": 412}},
                "steps_skipped": ["s007"]}
    text = _visible_text(DiagnosisReport().render(document, run_dir, None).read_text())
    assert "Left out, the logger clipped them" in text
    assert "f1-a400 (v_sz: 412 samples)" in text
    assert "Left out, not synchronised (no sync edges, no trigger): s007." in text
    plain = _visible_text(DiagnosisReport().render(DIAGNOSIS, run_dir, None).read_text())
    assert "Left out" not in plain
