"""``analysis.frf``: stepped-sine frequency-response points per channel (method §4.4)."""

from __future__ import annotations

from pydantic import Field

from aatest.results._fields import PerChannel, Real
from aatest.results.base import BudgetRow, Certified


class FrfPoint(Certified):
    """One FRF point; it certifies two quantities, gain and phase, each with its own U."""

    frequency_hz: Real
    accel_dps2: Real
    gain_db: Real = Field(description="dB re 1 V/(°/s²)")
    phase_deg: Real = Field(description="unwrapped along frequency within the group")
    delay_s: Real
    delay_samples: Real
    thd: Real = Field(description="sensor THD, harmonics 2..H over the fundamental")
    snr_db: Real
    snr6_db: Real = Field(description="SNR of the first H harmonics (key name kept)")
    table_thd: Real
    table_snr_db: Real
    table_snr6_db: Real
    measured_accel_dps2: Real
    gain_v_per_dps2: Real
    re: Real
    im: Real
    u_gain_db: Real
    u_phase_deg: Real
    u_delay_s: Real
    u_local_rel: Real | None = Field(
        None, ge=0, description="u of the ratio at the bin from the ratio's noise in the bins "
        "3–40 away, relative (= phase, rad); coherent records only")
    u_segments_gain_rel: Real | None = Field(
        None, ge=0, description="Type A u of the gain from the spread of the Hann-weighted "
        "segments' ratios, relative")
    u_segments_phase_rad: Real | None = Field(
        None, ge=0, description="Type A u of the phase from the spread of the Hann-weighted "
        "segments' ratios, rad")
    segments_dof: Real | None = Field(
        None, ge=0, description="effective degrees of freedom of the segment Type A "
        "(overlap-corrected)")
    segments: int | None = Field(None, ge=1, description="segments the ratio is averaged over")
    cycles_per_segment: int | None = Field(None, ge=1, description="whole cycles per segment")
    coherent: bool
    group: str
    step: str
    sample_rate_hz: Real
    gain_expanded_uncertainty_db: Real | None = Field(None, ge=0, description="U of gain, dB")
    phase_expanded_uncertainty_deg: Real | None = Field(None, ge=0, description="U of phase, °")
    phase_coverage_factor: Real | None = Field(
        None, ge=0, description="k of the phase's U (the point's coverage_factor is the gain's; "
        "they differ when a Type A with few degrees of freedom governs one of them)")
    gain_budget: list[BudgetRow] = Field(default_factory=list)
    phase_budget: list[BudgetRow] = Field(default_factory=list)
    gain_measurand: str = Field("", description="the precise gain quantity")
    phase_measurand: str = Field("", description="the precise phase quantity")


class FrfResult(PerChannel[list[FrfPoint]]):
    """Channel → FRF points sorted by group and frequency."""
