"""The report plugins (entry points in ``aatest.reports``): self-contained HTML files.

Each reporter builds a view model from the typed results (:mod:`.context`), renders its Jinja2
template in the sandbox (:mod:`.sandbox`) — the shipped one from ``aatest/reports`` or a lab's
own from ``template_dir`` — and writes the file atomically into the run directory. The signing
key's fingerprint, when the runner put it in ``results.signature``, is printed on the page
and stated in a ``<meta name="aatest-key-fingerprint">`` tag that ``aatest verify`` checks.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any, ClassVar

from pydantic import BaseModel, ConfigDict

from aatest.plugins.report import confined, pdf
from aatest.plugins.report.certificate import build_certificate
from aatest.plugins.report.context import ALL_SECTIONS, build_context, build_diagnosis_context
from aatest.plugins.report.sandbox import load_template, render_loaded
from aatest.plugins.report.traceability import hashed_ahead
from aatest.results import RunResults


class ReportConfig(BaseModel):
    """Options of every HTML report (uncertainties and verdicts are the engine's, not options)."""

    model_config = ConfigDict(extra="forbid")
    #: draw our own matplotlib plots (analysis figures are always included)
    plots: bool = True


def _write(path: Path, html: str) -> Path:
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(html, encoding="utf-8")
    os.replace(tmp, path)
    return path


class _HtmlReport:
    """Shared render path; subclasses name their template, title and sections.

    ``render`` receives the typed record (:class:`aatest.results.RunResults`); the diagnosis
    report receives the document of ``aatest diagnose`` instead.
    """

    Config: ClassVar[type[ReportConfig]] = ReportConfig
    template: ClassVar[str]
    title: ClassVar[str]
    sections: ClassVar[frozenset[str]] = ALL_SECTIONS
    output_name: ClassVar[str] = "report.html"
    #: the render reads only the typed record it is handed, never results.json: the engine
    #: writes that file meanwhile (:func:`aatest.engine.run.session._results_written`)
    renders_from_record: ClassVar[bool] = True
    #: what the report presents: a run's results (``run``), or the document of another
    #: command (``diagnose``): a procedure may choose only a ``run`` report
    #: (:func:`aatest.engine.plan_checks.template_problems`)
    renders: ClassVar[str] = "run"

    def __init__(self, config: ReportConfig | None = None) -> None:
        self.config = config if config is not None else self.Config()

    def context(self, results: RunResults, run_dir: Path) -> dict[str, Any]:
        return build_context(results, run_dir, self.template, self.title, self.sections,
                             self.config.plots)

    @contextlib.contextmanager
    def preparing(self, run_dir: Path | None = None) -> Iterator[None]:
        """Start the confined render's process now, while the caller still works (writing
        results.json): its imports (≈ 0.4 s CPU) and its compile of this report's shipped
        template then overlap that work; it is ended on exit
        when no render took it (:func:`.confined.prestarted`). Given the ``run_dir`` to
        render into, hash its recording meanwhile too (:func:`.traceability.hashed_ahead`)."""
        with contextlib.ExitStack() as stack:
            stack.enter_context(confined.prestarted(f"{self.template}.html.j2"))
            if run_dir is not None:
                stack.enter_context(hashed_ahead(run_dir))
            yield

    @classmethod
    def check_template(cls, template_dir: Path | None = None) -> None:
        """Load the template in the sandbox, as :meth:`render` will (the preflight of a run:
        a template that does not load fails before anything moves)."""
        load_template(f"{cls.template}.html.j2", template_dir)

    def render(self, results: RunResults, run_dir: Path, template_dir: Path | None) -> Path:
        """Render ``results`` into ``run_dir/<output_name>`` and return that path."""
        run_dir = Path(run_dir)
        template = load_template(f"{self.template}.html.j2", template_dir)  # fail before work
        html = render_loaded(template, self.context(results, run_dir))
        return _write(run_dir / self.output_name, html)

    def render_pdf(self, report: Path) -> Path:
        """Print the rendered ``report`` to ``report.pdf`` beside it (the engine's PDF seam)."""
        return pdf.render_pdf(report)


class CalibrationCertificate(_HtmlReport):
    """Calibration certificate: every calibrated parameter with U (k = 2) and its verdict."""

    class Config(ReportConfig):
        """Options of the calibration certificate."""

    template = "calibration-certificate"
    title = "Calibration certificate"

    def context(self, results: RunResults, run_dir: Path) -> dict[str, Any]:
        """The measurement view plus the ISO/IEC 17025 §7.8 content (:mod:`.certificate`)."""
        view = super().context(results, run_dir)
        trace = view["trace"]
        view["cert"] = build_certificate(
            results, run_dir, [c["name"] for c in view["channels"]], view["rule"],
            trace.procedure_sha256, trace.recording_sha256, view["report"]["generated_utc"])
        return view


class FrequencyResponseReport(_HtmlReport):
    """Stepped-sine frequency response: FRF points with U, fitted transfer functions, Bode."""

    class Config(ReportConfig):
        """Options of the frequency-response report."""

    template = "frequency-response"
    title = "Frequency-response report"
    sections = frozenset({"sync", "frf", "transfer_function"})


class MisalignmentReport(_HtmlReport):
    """Pivoted misalignment test: angles with U, cross-axis ratios, complex-plane view."""

    class Config(ReportConfig):
        """Options of the misalignment report."""

    template = "misalignment"
    title = "Misalignment report"
    sections = frozenset({"sync", "misalignment"})


class DiagnosisReport(_HtmlReport):
    """``aatest diagnose``: residual views, ranked candidates, findings, before/after."""

    class Config(ReportConfig):
        """Options of the diagnosis report."""

    template = "diagnosis"
    title = "Diagnosis"
    output_name = "diagnosis.html"
    renders = "diagnose"

    def context(self, results: Mapping[str, Any], run_dir: Path  # type: ignore[override]
                ) -> dict[str, Any]:
        """The view of the diagnosis document of ``aatest diagnose`` (not a run's results)."""
        return build_diagnosis_context(results, run_dir)

    def render(self, results: Mapping[str, Any], run_dir: Path,  # type: ignore[override]
               template_dir: Path | None) -> Path:
        """Render the diagnosis document (``aatest diagnose`` hands it over, not the engine)."""
        return super().render(results, run_dir, template_dir)  # type: ignore[arg-type]
