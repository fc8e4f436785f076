"""The ISO/IEC 17025 §7.8 content of a calibration certificate, prepared for the template.

Everything here is read from the typed results — the temperatures measured during the
calibration too (``logged_temperature``, summarised when the run was analysed): the issuing lab
(``metadata.lab``, written from the lab profile before signing), the item, the method and its
hash, the dates, the results with U, k and coverage probability and their measurands, the
reference's traceability, the conformity statement under the engine's decision rule,
adjustments, the signatory, and who confirmed each operator prompt and how. Nothing is
evaluated here: values, uncertainties and verdicts are the engine's; what the run did not record
is printed as "not recorded", never invented.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from aatest.plugins.report.stated import frf_points, static_values
from aatest.results import RunResults
from aatest.results.quantities import QUANTITIES, finite

#: the ISO/IEC 17025 §7.8.2.1 items the certificate covers, in the order they are printed
ITEMS = ("title", "lab", "identification", "item", "method", "dates", "environment",
         "results", "measurands", "traceability", "conformity", "adjustment", "signatory",
         "pages")

#: measurand of each certified quantity when the results state none
MEASURANDS: dict[str, str] = {
    "scale_factor": "scale factor: linear coefficient of the best straight line of output "
                    "voltage against angular acceleration about the sensitive axis, over the "
                    "sine's ±α at its frequency f (the non-linearity is reported separately)",
    "bias": "bias: output voltage at zero angular acceleration, (A+ + A−)/2 of the means with "
            "the input axis up and down",
    "g_sensitivity": "g-sensitivity: output change per g of specific force along the input "
                     "axis, expressed as equivalent angular acceleration, (A+ − A−)/2 ÷ scale",
    "bias_coefficient_v_per_c": "bias temperature coefficient: slope of the bias against the "
                                "sensor temperature over the chamber steps",
    "scale_coefficient_per_c": "scale-factor temperature coefficient: relative slope of the "
                               "scale factor against the sensor temperature",
    "frf_gain": "FRF gain: magnitude of the complex ratio of the fundamentals of output volts "
                "and angular acceleration about the sensitive axis at f (steady state, mean of "
                "Hann-weighted segments of whole cycles)",
    "frf_phase": "FRF phase: argument of the same complex ratio of the fundamentals at f",
}

#: how each confirmation channel is named on the certificate
_VIA = {"tty": "ask (confirmed at the terminal)", "station": "station (confirmed in the "
        "operator's browser station)", "auto": "auto (confirmed UNATTENDED by --confirm-prompts "
        "auto: nobody checked the instruction was carried out)"}


@dataclass(frozen=True)
class Environment:
    """Temperatures logged during the calibration, °C (None: nothing logged them)."""

    min_c: float | None
    mean_c: float | None
    max_c: float | None
    samples: int
    source: str


@dataclass(frozen=True)
class ResultRow:
    """One certified value as the certificate states it."""

    channel: str
    quantity: str
    value: float
    unit: str
    expanded_uncertainty: float | None
    coverage_factor: float | None
    coverage_probability: float | None
    measurand: str
    at: str = ""
    #: significant digits the value is printed with (the quantity registry's rule)
    digits: int = 6


@dataclass(frozen=True)
class Certificate:
    """The §7.8 view of one calibration (see :data:`ITEMS`)."""

    identification: str
    numbered: bool
    lab: Mapping[str, Any]
    item: Mapping[str, Any]
    method: Mapping[str, Any]
    calibrated_utc: str
    issued_utc: str
    environment: Environment
    results: list[ResultRow]
    traceability: list[tuple[str, str]]
    traceability_source: str
    conformity: str
    adjustment: Mapping[str, Any]
    signatories: list[Mapping[str, str]]
    prompts: list[dict[str, str]]
    confirmation: str
    unattended: bool
    notes: list[str] = field(default_factory=list)

    @property
    def measurands(self) -> list[tuple[str, str]]:
        """(quantity, definition) of every quantity certified, once each, in order."""
        seen: dict[str, str] = {}
        for row in self.results:
            seen.setdefault(row.quantity, row.measurand)
        return list(seen.items())


def _lab(results: RunResults) -> dict[str, Any]:
    if results.metadata.lab is not None:
        return dict(results.metadata.lab)
    return {"name": "aatest lab", "address": "", "accreditation": None, "signatories": [],
            "default_profile": True}


def environment(results: RunResults) -> Environment:
    """Min/mean/max of the temperatures logged during the calibration (docs: §7.8.4.1 a), as
    the analysis summarised them into the results (never read back from the recording)."""
    logged = results.logged_temperature
    if logged is None:  # analysed before results.json carried the summary
        return Environment(None, None, None, 0, "not in these results")
    return Environment(logged.min_c, logged.mean_c, logged.max_c, logged.samples, logged.source)


def _measurand(stated: str, key: str) -> str:
    return stated or MEASURANDS[key]  # the engine's own text when the results carry one


def _level_at(entry: Any) -> str:
    """Where a scale factor belongs: its level, frequency and set-point (empty for others)."""
    accel = getattr(entry, "accel_dps2", None)
    if accel is None:
        return ""
    temperature = entry.temperature_c
    return (f"{accel:g} °/s², {entry.frequency_hz:.4g} Hz"
            + (f", {temperature:g} °C" if temperature is not None else ""))


def _level_rows(results: RunResults, ch: str) -> list[ResultRow]:
    """The scale factor at every other acceleration level and set-point."""
    block = results.analysis.scale_factor
    head = block.get(ch) if block else None
    if head is None:
        return []
    q = QUANTITIES["scale_factor"]
    return [ResultRow(ch, q.name, lv.scale_v_per_dps2, q.unit, lv.expanded_uncertainty,
                      lv.coverage_factor, lv.coverage_probability,
                      _measurand(lv.measurand, q.key), _level_at(lv), q.digits)
            for lv in head.levels
            if (lv.accel_dps2, lv.temperature_c) != (head.accel_dps2, head.temperature_c)]


def result_rows(results: RunResults, channels: Sequence[str]) -> list[ResultRow]:
    """Every certified value with its unit, U, k, coverage probability and measurand."""
    rows = []
    gain, phase = QUANTITIES["frf_gain"], QUANTITIES["frf_phase"]
    for ch in channels:
        for q, entry, value in static_values(results, ch):
            rows.append(ResultRow(ch, q.quantity.name, value, q.quantity.unit,
                                  finite(q.u(entry)), entry.coverage_factor,
                                  entry.coverage_probability,
                                  _measurand(entry.measurand, q.quantity.key),
                                  _level_at(entry), digits=q.quantity.digits))
        rows += _level_rows(results, ch)
        for p in frf_points(results, ch):
            at = f"{p.frequency_hz:.4g} Hz"
            if finite(p.gain_db) is not None:
                rows.append(ResultRow(ch, gain.name, p.gain_db, gain.unit,
                                      p.gain_expanded_uncertainty_db, p.coverage_factor,
                                      p.coverage_probability,
                                      _measurand(p.gain_measurand or p.measurand, gain.key), at,
                                      gain.digits))
            if finite(p.phase_deg) is not None:
                # the phase has its own k (its Type A's degrees of freedom)
                rows.append(ResultRow(ch, phase.name, p.phase_deg, phase.unit,
                                      p.phase_expanded_uncertainty_deg,
                                      p.phase_coverage_factor or p.coverage_factor,
                                      p.coverage_probability,
                                      _measurand(p.phase_measurand, phase.key), at, phase.digits))
    return rows


def _flatten(value: Any) -> str:
    if isinstance(value, Mapping):
        return "; ".join(f"{k}: {_flatten(v)}" for k, v in value.items())
    if isinstance(value, list | tuple):
        return "; ".join(_flatten(v) for v in value)
    return str(value)


def reference_traceability(results: RunResults) -> tuple[list[tuple[str, str]], str]:
    """(item, statement) rows of the reference's traceability and where they were stated:
    the uncertainty stage's record of the rig description (``metadata.traceability``), else
    the rig description's own ``traceability``."""
    typed = results.metadata.traceability
    if typed is not None and typed.instruments:
        return [(name.capitalize(), f"certificate {i.cert_id} of {i.cert_date} by {i.lab}; "
                 f"accuracy {i.accuracy}") for name, i in typed.instruments.items()], \
            "rig description" if typed.stated else "stated defaults (no rig description)"
    for rig in (results.metadata.recorded("rig"), results.rig):
        stated = rig.get("traceability") if isinstance(rig, Mapping) else None
        if isinstance(stated, Mapping) and stated:
            return [(str(k), _flatten(v)) for k, v in stated.items()], "rig description"
        if isinstance(stated, str) and stated:
            return [("reference", stated)], "rig description"
    return [], "not stated"


def _conformity(results: RunResults, rule: str) -> str:
    rails = (" Each sensor channel's record is also checked against the sensor logger's stated "
             "input range: any sample at its limits means the logger clipped the output, and "
             "that channel fails." if any(v.limit_source == "logger" for v in results.verdicts)
             else "")
    if all(v.limit_source == "logger" for v in results.verdicts):
        return ("No conformity statement: no quantity was judged against a specification."
                + rails)
    sources = {v.limit_source for v in results.verdicts if v.limit_source} - {"logger"}
    origin = {frozenset({"procedure"}): "the procedure's acceptance limits",
              frozenset({"datasheet"}): "the sensor's datasheet limits"}.get(
        frozenset(sources), "the procedure's acceptance limits and, where it sets none, the "
        "sensor's datasheet limits")
    text = (f"Conformity with {origin}, decided by the engine under the decision rule "
            f"'{rule}' (ILAC-G8): overall {results.overall}; each judged quantity with its "
            "limit (and where the limit came from), U and verdict is listed below.")
    text += rails
    if results.overall == "incomplete":
        text += (" The calibration is incomplete: quantities the procedure asked for were not "
                 "measured (marked 'not judged', with the reason).")
    return text


def _adjustment(results: RunResults) -> dict[str, Any]:
    stated = results.metadata.adjustment
    if stated is not None and stated.get("made"):
        return {"made": True, "as_found": stated.get("as_found"),
                "as_left": stated.get("as_left"), "text": str(stated.get("note") or "")}
    return {"made": False, "text": "No adjustment was made: the results are both the "
                                   "as-found and the as-left values."}


def _prompts(results: RunResults) -> tuple[list[dict[str, str]], str, bool]:
    """Who confirmed which operator prompt, when and through which channel; the mode."""
    texts = {s.id: str(getattr(s, "prompt", None) or "") for s in results.steps}
    rows = []
    for answer in results.metadata.prompt_answers:
        step = answer.step_id or "—"
        rows.append({"step_id": step, "prompt": texts.get(step, ""),
                     "answered_by": answer.answered_by or "—",
                     "answered_utc": answer.answered_utc or "—", "via": answer.via or "—"})
    modes = sorted({r["via"] for r in rows})
    if not rows:
        return rows, "no operator prompts in this run", False
    return rows, "; ".join(_VIA.get(m, m) for m in modes), "auto" in modes


def _item(results: RunResults) -> dict[str, Any]:
    unit = results.metadata.unit()
    return {"description": "angular accelerometer", "model": unit.model or "not recorded",
            "serial": unit.serial or "not recorded", "channels": results.metadata.sensors}


def _method(results: RunResults, procedure_sha256: str) -> dict[str, str]:
    meta = results.metadata
    return {"procedure": results.procedure or meta.procedure or "—",
            "sha256": procedure_sha256, "standard": meta.standard or "not stated",
            "description": "angular acceleration generated by a position turntable (sine "
                           "profile); reference from the table's logs; evaluation per IEEE "
                           "Std 671 (test procedures) and in the manner of ISO 16063 "
                           "(sensitivity as a complex ratio at the fundamental)"}


def build_certificate(results: RunResults, run_dir: Path, channels: Sequence[str],
                      rule: str, procedure_sha256: str, recording_sha256: str,
                      issued_utc: str) -> Certificate:
    """The §7.8 view of ``results`` (issued at ``issued_utc``, ISO 8601)."""
    lab = _lab(results)
    number = results.certificate_number
    identification = number or f"{results.procedure or 'run'}-{recording_sha256[:12]}"
    prompts, confirmation, unattended = _prompts(results)
    trace_rows, trace_source = reference_traceability(results)
    notes = []
    if lab.get("default_profile"):
        notes.append("No lab profile was given (--lab or AATEST_LAB): the issuing lab's "
                     "identity, accreditation and signatories are not stated.")
    if not number:
        notes.append("No certificate number was issued (no records store): the run's "
                     "identifier is the procedure and the recording's SHA-256 prefix.")
    return Certificate(
        identification=identification, numbered=bool(number), lab=lab, item=_item(results),
        method=_method(results, procedure_sha256),
        calibrated_utc=results.metadata.started_utc or "not recorded", issued_utc=issued_utc,
        environment=environment(results), results=result_rows(results, channels),
        traceability=trace_rows, traceability_source=trace_source,
        conformity=_conformity(results, rule), adjustment=_adjustment(results),
        signatories=[dict(s) for s in lab.get("signatories") or [] if isinstance(s, Mapping)],
        prompts=prompts, confirmation=confirmation, unattended=unattended, notes=notes)
