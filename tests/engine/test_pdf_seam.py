"""``--pdf`` goes through the report plugin's optional ``render_pdf`` capability.

The engine imports no report module (tests/test_architecture.py); it asks the loaded report
plugin for a PDF through :class:`~aatest.engine.interfaces.PdfRenderer`, and refuses (exit 2)
a report that cannot print one instead of leaving the PDF out silently.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from aatest.engine import registry
from aatest.engine.analysis.results_file import write_results
from aatest.engine.errors import InputError
from aatest.engine.interfaces import PdfRenderer, Reporter
from aatest.engine.run import session
from aatest.plugins.report.html import CalibrationCertificate
from aatest.results import RunResults


class _HtmlOnly:
    """A report plugin that renders HTML and has no PDF capability."""

    def __init__(self, config: Any = None) -> None:
        self.config = config

    def render(self, results: RunResults, run_dir: Path, template_dir: Path | None) -> Path:
        path = run_dir / "report.html"
        path.write_text(f"<p>{results.procedure}</p>", encoding="utf-8")
        return path


class _WithPdf(_HtmlOnly):
    """The same report, able to print itself (records what it was asked to print)."""

    printed: list[Path] = []  # noqa: RUF012 - a test spy shared by the instances the engine makes

    def render_pdf(self, report: Path) -> Path:
        self.printed.append(report)
        pdf = report.with_name("report.pdf")
        pdf.write_bytes(b"%PDF-1.7 test")
        return pdf


@pytest.fixture
def run_dir(tmp_path: Path) -> Path:
    results = RunResults(procedure="pdf-seam", metadata={"report_template": "test-report"})
    write_results(results, tmp_path)
    return tmp_path


def _install(monkeypatch: pytest.MonkeyPatch, target: type) -> None:
    info = registry.PluginInfo("report", "test-report", target, "test-dist", "0")
    monkeypatch.setattr(registry, "load", lambda kind, name: info)


def test_shipped_reports_have_the_capability() -> None:
    report = CalibrationCertificate()
    assert isinstance(report, Reporter) and isinstance(report, PdfRenderer)
    assert not isinstance(_HtmlOnly(), PdfRenderer)


def test_report_without_render_pdf_is_refused_with_exit_2(
    run_dir: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    _install(monkeypatch, _HtmlOnly)
    with pytest.raises(InputError, match="report 'test-report' cannot print a PDF") as refused:
        session.report(run_dir, None, None, pdf=True)
    assert refused.value.exit_code == 2
    assert (run_dir / "results.json").is_file() and not (run_dir / "report.pdf").exists()
    session.report(run_dir, None, None, pdf=False)  # without --pdf the same report renders
    assert (run_dir / "report.html").read_text(encoding="utf-8") == "<p>pdf-seam</p>"


def test_render_pdf_is_asked_for_the_rendered_report(
    run_dir: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    _install(monkeypatch, _WithPdf)
    _WithPdf.printed.clear()
    report = session.report(run_dir, None, None, pdf=True)
    assert _WithPdf.printed == [report] and report == run_dir / "report.html"
    assert (run_dir / "report.pdf").read_bytes().startswith(b"%PDF-")
