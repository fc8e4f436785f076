"""``analysis.sync``: the clock relation between the table and the sensor logger (method §2)."""

from __future__ import annotations

from pydantic import Field

from aatest.results._fields import Real
from aatest.results.base import ResultModel


class ClockFields(ResultModel):
    """``t_table = offset_s + t_daq·(1 + drift_ppm·1e-6)`` and how well the edges agree."""

    drift_ppm: Real = Field(description="DAQ clock drift against the table clock, ppm")
    offset_s: Real = Field(description="table time at DAQ time zero, s")
    residual_rms_us: Real = Field(description="RMS of the edge residuals, µs")
    edges_used: int = Field(ge=0, description="paired sync-pulse edges")
    drift_u_ppm: Real = Field(0.0, description="standard uncertainty of the drift, ppm")


class StepSync(ClockFields):
    """The clock relation of one recorded step."""

    step: str = Field(description="step id")
    offset_u_s: Real = Field(0.0, description="standard uncertainty of the offset, s (without "
                             "latch times: of the alignment at the record's centre)")
    latched: bool = Field(True, description="edge times from latch times (else from the "
                          "sample that registered each edge, known to one sample)")
    slips_corrected: int = Field(0, ge=0, description="edge registrations one sample off "
                                 "the pattern, undone before the fit (no latch times)")
    fit_coverage: Real = Field(1.0, description="share of the DAQ record's span that the "
                               "paired edges span (below 1: a table log covering part of the "
                               "record; the fitted drift is carried over the rest)")
    extrapolation_u_s: Real = Field(0.0, description="standard uncertainty the carried drift "
                                    "adds to the time alignment at the record point farthest "
                                    "from the paired edges, s (drift_u × distance)")
    drift_source: str | None = Field(None, description="what fixed the drift: 'latch times', "
                              "'edges' (without latch times: bounded to the drifts every edge "
                              "interval allows) or 'edges + sine phase trend' (narrowed inside "
                              "that range by the sensor-vs-table phase trend of the sine steps); "
                              "absent from results written before it was stated")


class SyncResult(ClockFields):
    """Overall relation (edge-weighted drift, pooled residual) and one entry per step.

    ``offset_s`` is that of the first step; each record has its own start.
    """

    drift_spread_ppm: Real = Field(0.0, description="standard deviation of the step drifts, ppm")
    steps: list[StepSync] = Field(default_factory=list)
