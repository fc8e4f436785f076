"""What a partial clock fit adds to the static results, and the output-noise budget.

A long static record whose table log covers only its head (a finite controller buffer) is
synchronised on the edges both loggers hold; the fitted drift is carried over the rest
(docs/method.md §2). The record's window on the DAQ clock — from the table record's start to
its end — is then known at the start to the offset's uncertainty ``u_off`` and at the far
end to ``√(u_off² + u_ext²)`` (``u_ext``: the carried drift's uncertainty times the distance
from the fitted edges, the sync result's ``extrapolation_u_s``). A window edge moved by δ
changes a record mean by δ·(V(edge) − mean)/T and its mean square by
δ·((V(edge) − mean)² − σ²)/T; with V(edge) − mean of the order of the output noise σ this is

* mean (bias): u = σ·√(2·u_off² + u_ext²)/T, the two edges' samples independent;
* RMS (noise): u = σ·√(2·u_off² + u_ext²)/(√2·T) (E[(x² − σ²)²] = 2σ⁴ for Gaussian noise).

Both are stated per record in the budget row with the record's fit coverage, so the
certificate says how much of the record the clock fit spans and what carrying it costs.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

from aatest.metrology.uncertainty import components as comp
from aatest.metrology.uncertainty.gum import Input, Measurand, Ops
from aatest.metrology.uncertainty.statistics import finite
from aatest.results import RunResults
from aatest.results.sync import StepSync


def _partial_steps(results: RunResults, step_ids: Sequence[str]) -> list[tuple[StepSync, float]]:
    """(sync entry, record length s) of the listed steps whose table log covers part of the
    record only (fewer table samples than planned: the clock fit is carried over the rest)."""
    sync = results.analysis.sync
    partial = {s.id: float(s.duration_s) for s in results.steps
               if s.table_samples is not None and s.table_samples < s.samples
               and s.duration_s > 0}
    return [(entry, partial[entry.step]) for entry in (sync.steps if sync else [])
            if entry.step in step_ids and entry.step in partial]


def _window_u_s(entry: StepSync) -> float:
    """√(2·u_off² + u_ext²) of one record (s)."""
    return math.sqrt(2.0 * float(entry.offset_u_s) ** 2 + float(entry.extrapolation_u_s) ** 2)


def clock_coverage_input(results: RunResults, channel: str, step_ids: Sequence[str],
                         quantity: str, unit: str = "V") -> Input | None:
    """The budget row of the record window's alignment for a static mean (``quantity``
    ``"mean"``) or RMS (``"rms"``) over ``step_ids``; None when every record's clock fit
    spans it (nothing is carried).

    A mean is the mean over the records, so the per-record terms combine as √Σu²/n; an RMS is
    the largest record's (the judged one), so the largest term stands.
    """
    partial = _partial_steps(results, step_ids)
    if not partial:
        return None
    sigma_v, source = comp.noise_rms_v(results, channel)
    per_rms = 1.0 if quantity == "mean" else math.sqrt(2.0)
    terms = [sigma_v * _window_u_s(e) / (per_rms * t) for e, t in partial]
    u = (math.sqrt(sum(x * x for x in terms)) / max(len(step_ids), 1) if quantity == "mean"
         else max(terms))
    worst = min(partial, key=lambda p: float(p[0].fit_coverage))[0]
    formula = "σ·√(2u_off² + u_ext²)/T" if quantity == "mean" else \
        "σ·√(2u_off² + u_ext²)/(√2·T)"
    note = (f"measured: clock fit on the table log's edges spans {len(partial)} record(s) "
            f"partly (least: {float(worst.fit_coverage) * 100:.1f} % of {worst.step}), the "
            f"fitted drift carried over the rest adds u_ext = "
            f"{float(worst.extrapolation_u_s) * 1e6:.3g} µs at its far end (u_off = "
            f"{float(worst.offset_u_s) * 1e6:.3g} µs); {formula} with σ = "
            f"{sigma_v * 1e3:.2f} mV ({source}), "
            + (f"mean over {len(step_ids)} record(s)" if quantity == "mean"
               else "the largest record term"))
    return Input("clock_coverage", "synchronisation: record window (partial clock fit)", 0.0,
                 u, "normal", unit, note)


def _static_ids(results: RunResults) -> list[str]:
    return [s.id for s in results.steps_of_kind("static")]


def noise_measurand(results: RunResults, channel: str, c: Any) -> Measurand | None:
    """σ = σ̂·(1 + e_gain) + e_noise + e_clock  [V]: the largest DC–band RMS of the static
    records (the judged ``rms_max_v``).

    e_noise: the statistical uncertainty of an RMS over the band B and record T, σ/√(4·B·T)
    (ν ≈ 2·B·T independent values, u(σ̂)/σ = 1/√(2ν); B the band or, when narrower, the
    pre-sample filter's noise bandwidth); e_gain: the logger's gain accuracy;
    e_clock: the record window's alignment when the clock fit covers part of the record.
    """
    block = results.analysis.noise
    entry = block.get(channel) if block else None
    worst = finite(entry.rms_max_v) if entry is not None else None
    if entry is None or worst is None:
        return None
    band_hz = float(entry.band_hz)
    static = results.steps_of_kind("static")
    record_s = min((float(s.duration_s) for s in static if s.duration_s), default=0.0)
    if record_s <= 0:
        return None
    noise_hz = min(band_hz, float(c.noise_bandwidth_hz))  # the pre-sample filter's corner
    inputs = [
        Input("noise", "statistics of the RMS (band × record)", 0.0,
              worst / math.sqrt(4.0 * noise_hz * record_s), "normal", "V",
              f"measured: σ/√(4·B·T), B = {noise_hz:g} Hz (the band up to {band_hz:g} Hz "
              f"behind the pre-sample filter), T = {record_s:g} s", "A"),
        comp.logger_gain(c),
    ]
    ids = _static_ids(results)
    clock = clock_coverage_input(results, channel, ids, "rms")
    if clock is not None:
        inputs.append(clock)

    def model(ops: Ops, x: Mapping[str, Any]) -> Any:
        return worst * (1.0 + x["logger_gain"]) + x["noise"] + x.get("clock_coverage", 0.0)

    definition = (f"output noise of {channel}: RMS of the output at rest between DC and "
                  f"{band_hz:g} Hz (mean removed), the largest over the static records")
    return Measurand(f"noise {channel}", "V", model, tuple(inputs), definition)
