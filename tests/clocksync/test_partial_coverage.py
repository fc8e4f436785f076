"""Clock relation when the table log covers only part of the DAQ record (finite controller log).

The clocks are fitted on the edges both loggers hold and the drift carried over the rest; the
relation states how much of the record its edges span (``fit_coverage``) and what carrying
the drift adds to the time alignment at the far end (``extrapolation_u_s``). The reference is
the relation fitted on the whole table log of the same record (same seed, same clocks).
"""

from __future__ import annotations

import numpy as np
import pytest
from recording_data import sine_step, step_logs

from aatest.clocksync.freeze_pulse import ClockRelation, clock_relation
from aatest.engine.logs import SampledLog
from aatest.recording.dataset import StepData

SAMPLES = 200_000  # 100 s at 2 kHz: 10 000 pulse edges


def _rows(log: SampledLog, keep: np.ndarray, latch: bool) -> SampledLog:
    channels = {k: v[keep] for k, v in log.channels.items() if latch or k != "fp_latch_s"}
    return SampledLog(log.source, log.sample_rate_hz, log.time_s[keep], channels, dict(log.units))


def _relations(pieces: list[tuple[float, float]], latch: bool
               ) -> tuple[ClockRelation, ClockRelation, SampledLog]:
    step = sine_step("s01", SAMPLES)
    table, daq = step_logs(step, 4)
    every = np.ones(len(table), dtype=bool)
    keep = np.zeros(len(table), dtype=bool)
    for lo, hi in pieces:
        keep[int(lo * len(table)):int(hi * len(table))] = True
    full = clock_relation(StepData(step, _rows(table, every, latch), daq))
    part = clock_relation(StepData(step, _rows(table, keep, latch), daq))
    return full, part, daq


@pytest.mark.parametrize("latch", [True, False])
def test_head_of_the_record_fits_the_clocks_and_states_its_coverage(latch: bool) -> None:
    """The table holds the first 10 %: drift and far-end alignment agree with the whole fit
    within the stated uncertainties (3 σ), coverage ≈ 10 %."""
    full, part, daq = _relations([(0.0, 0.1)], latch)
    assert part.fit_coverage == pytest.approx(0.1, abs=0.01)
    assert full.fit_coverage == pytest.approx(1.0, abs=0.01)
    assert abs(part.drift_ppm - full.drift_ppm) <= 3 * np.hypot(part.drift_u_ppm,
                                                                full.drift_u_ppm)
    end = float(daq.time_s[-1])
    beyond = end - part.fit_span_daq_s[1]  # type: ignore[index]
    assert part.extrapolation_u_s == pytest.approx(part.drift_u_ppm * 1e-6 * beyond, rel=1e-12)
    assert part.extrapolation_u_s > 10 * full.extrapolation_u_s
    error_s = abs(float(part.to_table_s(end) - full.to_table_s(end)))
    budget_s = np.hypot(part.extrapolation_u_s, part.offset_u_s + full.offset_u_s)
    assert error_s <= 3 * budget_s
    assert part.as_dict()["fit_coverage"] == part.fit_coverage


def test_log_delivered_in_pieces_spans_the_record() -> None:
    """Three 5 % pieces at the start, middle and end: paired across the gaps, the fit spans
    ≈ 85 % of the record and nothing is extrapolated beyond a few seconds."""
    full, part, _ = _relations([(0.0, 0.05), (0.45, 0.5), (0.9, 0.95)], latch=True)
    assert part.fit_coverage == pytest.approx(0.95, abs=0.01)
    assert abs(part.drift_ppm - full.drift_ppm) <= 3 * np.hypot(part.drift_u_ppm,
                                                                full.drift_u_ppm)
    assert part.edges_used == pytest.approx(0.15 * full.edges_used, rel=0.02)
