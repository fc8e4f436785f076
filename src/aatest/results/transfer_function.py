"""``analysis.transfer_function``: transfer-function models per channel (method §4.4)."""

from __future__ import annotations

from pydantic import Field

from aatest.results._fields import ComplexPair, PerChannel, Real
from aatest.results.base import ResultModel


class XcorrDelay(ResultModel):
    """Input–output cross-correlation delay and whether it was strong enough to use."""

    delay_samples: int
    delay_s: Real
    strength: Real
    accepted: bool


class Candidate(ResultModel):
    """One candidate model (n poles, m zeros, a delay) with MATLAB-style metrics."""

    n: int
    m: int
    delay_samples: int
    delay_source: str = Field(description="none | xcorr | scan")
    fit_pct: Real = Field(description="validation fit, %")
    fit_id_pct: Real
    V: Real
    n_params: int
    N: int
    nAIC: Real  # noqa: N815 - MATLAB's name of the criterion, a results.json key (§1)
    FPE: Real
    stable: bool
    zeros_outside_unit_circle: int


class ContinuousModel(ResultModel):
    """Pole/zero-matched continuous equivalent of the chosen discrete model."""

    num: list[Real]
    den: list[Real]
    poles_rad_s: list[ComplexPair]
    natural_frequencies_hz: list[Real]
    damping: list[Real]
    delay_s: Real
    dc_gain: Real


class SecondOrderDelay(ResultModel):
    """K·ωn²/(s² + 2ζωn·s + ωn²)·e^{−sτ} with the logger's anti-alias filter de-embedded."""

    gain_v_per_dps2: Real
    natural_frequency_hz: Real
    damping: Real
    delay_s: Real
    #: standard uncertainties from the fit's Jacobian; ``None`` for a parameter on a bound
    u_natural_frequency_hz: Real | None
    u_damping: Real | None
    u_delay_s: Real | None
    fit_pct: Real
    deembedded_antialias_hz: Real | None = None
    #: parameters the fit holds on a bound (e.g. ``damping`` at 5: an overdamped pair): their
    #: values are limits of the fit, not estimates, and carry no stated uncertainty
    at_bound: list[str] = Field(default_factory=list)


class TfModel(ResultModel):
    """The chosen discrete model of one group of FRF points (contract keys first)."""

    poles: list[ComplexPair]
    zeros: list[ComplexPair]
    delay_s: Real
    fit_pct: Real
    nAIC: Real  # noqa: N815 - MATLAB's name of the criterion, a results.json key (§1)
    FPE: Real
    num: list[Real]
    den: list[Real]
    dt: Real
    n: int
    m: int
    delay_samples: int
    delay_source: str
    fit_id_pct: Real
    zeros_outside_unit_circle: int
    xcorr: XcorrDelay
    continuous: ContinuousModel
    candidates: list[Candidate]
    second_order_delay: SecondOrderDelay


class TransferFunctionChannel(TfModel):
    """The model of the channel's best group (highest median SNR), and every group's."""

    group: str
    groups: dict[str, TfModel]


class TransferFunctionResult(PerChannel[TransferFunctionChannel]):
    """Channel → transfer-function models."""
