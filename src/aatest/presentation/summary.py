"""What ``aatest run`` and ``aatest analyze`` report when they end, as one typed record.

The summary is built from the typed :class:`~aatest.results.RunResults` (never re-read from a
file): every certified quantity with value ± U (k), every verdict, the overall verdict, the
certificate number, the report's path, the lab time and the command's total wall time (not
only the step loop's). :mod:`aatest.presentation.terminal` prints it as a table or as JSON.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any

from aatest.results import RunResults
from aatest.results.quantities import finite, quantity
from aatest.results.rounding import round_measurement
from aatest.storage import Where

#: (analysis key, value field, U field or "" for the entry's ``expanded_uncertainty``,
#: quantity registry key) of every certified scalar, in the order a certificate lists them
CERTIFIED_FIELDS = (
    ("scale_factor", "scale_v_per_dps2", "", "scale_factor"),
    ("bias", "bias_v", "", "bias"),
    ("bias", "g_sensitivity_dps2_per_g", "g_sensitivity_expanded_uncertainty_dps2_per_g",
     "g_sensitivity"),
    ("temperature", "bias_coefficient_v_per_c", "", "bias_coefficient_v_per_c"),
    ("temperature", "scale_coefficient_per_c", "scale_coefficient_expanded_uncertainty_per_c",
     "scale_coefficient_per_c"),
)
#: report files a report plugin may leave in the bundle, the one to open first
REPORT_FILES = ("report.pdf", "report.html")


@dataclass(frozen=True)
class CertifiedRow:
    """One certified quantity of one channel: value ± U with coverage factor k."""

    quantity: str
    name: str
    channel: str
    value: float | None
    expanded_uncertainty: float | None
    coverage_factor: float | None
    unit: str
    text: str


@dataclass(frozen=True)
class VerdictRow:
    """One judged quantity: value ± U against its limit, and the decision."""

    quantity: str
    name: str
    channel: str
    value: float | None
    expanded_uncertainty: float | None
    limit: float | None
    unit: str
    rule: str
    verdict: str
    text: str
    limit_text: str


@dataclass(frozen=True)
class RunSummary:
    """The end of a run or analysis, as a person (or a script with ``--json-summary``) reads it."""

    command: str
    procedure: str
    model: str | None
    serial: str | None
    certified: list[CertifiedRow]
    verdicts: list[VerdictRow]
    overall: str
    certificate_number: str | None
    results_path: str
    report_path: str | None
    steps: int
    lab_duration_s: float
    run_wall_duration_s: float
    wall_duration_s: float
    analysis_errors: dict[str, str] = field(default_factory=dict)

    def as_json(self) -> dict[str, Any]:
        """The ``--json-summary`` document (plain JSON values)."""
        return asdict(self)


def _field(entry: Any, name: str) -> float | None:
    return finite(getattr(entry, name, None))


def certified_rows(results: RunResults) -> list[CertifiedRow]:
    """Every certified scalar the analyses produced, per channel, with its U and k."""
    rows = []
    present = results.analysis.present()
    for analysis_key, value_field, u_field, key in CERTIFIED_FIELDS:
        for channel, entry in (present.get(analysis_key) or {}).items():
            value = _field(entry, value_field)
            if value is None:
                continue
            u = _field(entry, u_field or "expanded_uncertainty")
            q = quantity(key)
            rows.append(CertifiedRow(
                key, q.name, channel, value, u, _field(entry, "coverage_factor"), q.unit,
                round_measurement(value, u, digits=q.digits).text(q.unit)))
    return rows


def verdict_rows(results: RunResults) -> list[VerdictRow]:
    """Every verdict with the quantity's display name and rounded value ± U."""
    rows = []
    for v in results.verdicts:
        q = quantity(v.quantity)
        text = ("not measured" + (f" ({v.reason})" if v.reason else "") if v.value is None
                else round_measurement(v.value, v.expanded_uncertainty,
                                       digits=q.digits).text(q.unit))
        limit_text = q.limit_text(v.limit)
        rows.append(VerdictRow(
            v.quantity, q.name, v.channel, v.value, v.expanded_uncertainty, v.limit, q.unit,
            v.rule, v.verdict, text, limit_text))
    return rows


def report_path(bundle: Where) -> Where | None:
    """The report the bundle holds (the PDF when one was printed)."""
    return next((bundle / n for n in REPORT_FILES if (bundle / n).is_file()), None)


def signed_report(bundle: Where) -> Where:
    """The report of ``bundle`` to verify: the first with its detached signature beside it,
    else the first there, else ``report.html`` (so that a bundle without any report is
    verified as one whose report is missing: a finding, not a usage error)."""
    from aatest.bundle.signature_format import signature_path

    reports = [bundle / n for n in REPORT_FILES if (bundle / n).is_file()]
    signed = [r for r in reports if signature_path(r).is_file()]
    return (signed or reports or [bundle / REPORT_FILES[-1]])[0]


def summarise(results: RunResults, bundle: Where, command: str,
              wall_duration_s: float) -> RunSummary:
    """The summary of ``results`` written to ``bundle`` by ``command``.

    ``wall_duration_s`` is the whole command's wall time (s), from start to this call;
    ``results.wall_duration_s`` stays the step loop's (the lab-to-wall ratio on record).
    """
    unit = results.metadata.unit()
    report = report_path(bundle)
    return RunSummary(
        command=command, procedure=results.procedure, model=unit.model, serial=unit.serial,
        certified=certified_rows(results), verdicts=verdict_rows(results),
        overall=results.overall, certificate_number=results.certificate_number,
        results_path=str(bundle / "results.json"),
        report_path=str(report) if report is not None else None,
        steps=len(results.steps), lab_duration_s=float(results.lab_duration_s),
        run_wall_duration_s=float(results.wall_duration_s),
        wall_duration_s=wall_duration_s, analysis_errors=dict(results.analysis_errors))
