"""Display names, unit symbols and significant digits of every reported quantity, in one place.

The certificate, the other reports, the station, ``aatest history`` and the terminal summary
show a quantity by its :class:`Quantity` entry here — never by its results.json field name.
``json_unit`` is the unit string results.json carries for the quantity (``Verdict.unit``,
unchanged for compatibility); ``unit`` is the symbol a person reads.

>>> QUANTITIES["nonlinearity_pct_fr"].name
'Nonlinearity, % of full range'
>>> QUANTITIES["scale_factor"].show(0.0040139, 1.2e-6)
'4.0139e-03 ± 1.2e-06 V/(°/s²)'
"""

from __future__ import annotations

from dataclasses import dataclass

from aatest.results._fields import finite
from aatest.results.digits import COUNT, U_DIGITS, significant
from aatest.results.rounding import measurement_text

__all__ = [
    "ANALYSES",
    "DISTRIBUTIONS",
    "QUANTITIES",
    "REFERENCE_METHODS",
    "U_DIGITS",
    "Quantity",
    "analysis_name",
    "finite",
    "quantity",
    "reference_name",
    "significant",
]

@dataclass(frozen=True)
class Quantity:
    """How a person reads one quantity: its name, unit symbol and significant digits."""

    key: str
    name: str
    unit: str
    digits: int
    json_unit: str = ""

    def value_text(self, value: float | None) -> str:
        """The value with the quantity's significant digits (``—`` when not finite)."""
        return significant(value, self.digits)

    def show(self, value: float | None, u: float | None = None) -> str:
        """``value ± U unit`` rounded per GUM 7.2.6 (:mod:`aatest.results.rounding`); without a
        U the value keeps the quantity's significant digits."""
        return measurement_text(value, u, self.unit, digits=self.digits)

    def limit_text(self, limit: float | None) -> str:
        """The acceptance limit as a person reads it: ``±1.000 %`` on a value's magnitude,
        ``at most 0 samples`` for a count (a count has no sign)."""
        if limit is None:
            return "—"
        if self.digits == COUNT:
            return f"at most {self.show(limit)}"
        return f"±{self.show(limit)}"


def _q(key: str, name: str, unit: str, digits: int, json_unit: str | None = None) -> Quantity:
    return Quantity(key, name, unit, digits, unit if json_unit is None else json_unit)


#: every certified, judged or recorded quantity, by the key results.json and the records use
QUANTITIES: dict[str, Quantity] = {q.key: q for q in (
    # certified values (uncertainty budgets, certificate rows, records)
    _q("scale_factor", "Scale factor", "V/(°/s²)", 6),
    _q("bias", "Bias", "V", 6),
    _q("g_sensitivity", "g-sensitivity", "(°/s²)/g", 4),
    _q("bias_coefficient_v_per_c", "Bias temperature coefficient", "V/°C", 4),
    _q("scale_coefficient_per_c", "Scale-factor temperature coefficient", "1/°C", 4),
    _q("frf_gain", "FRF gain", "dB", 5),
    _q("frf_phase", "FRF phase", "°", 4, "deg"),
    _q("misalignment", "Misalignment angle", "°", 4, "deg"),
    _q("linearity_l_dps2", "(Non)linearity L (RMS from the ideal line)", "°/s²", 3),
    # judged quantities (verdicts)
    _q("scale_factor_deviation_pct", "Scale-factor deviation from nominal", "%", 4),
    _q("bias_deviation_v", "Bias deviation from nominal", "V", 4),
    _q("nonlinearity_pct_fr", "Nonlinearity, % of full range", "% FR", 3),
    _q("g_sensitivity_dps2_per_g", "g-sensitivity", "(°/s²)/g", 4),
    _q("cross_axis_ratio", "Cross-axis ratio", "", 4, "1"),
    _q("misalignment_deg", "Misalignment angle", "°", 4, "deg"),
    _q("bias_temperature_v_per_c", "Bias temperature coefficient", "V/°C", 4),
    _q("scale_temperature_per_c", "Scale-factor temperature coefficient", "1/°C", 4),
    _q("noise_rms_v", "Output noise (RMS)", "V", 3),
    # judged on every run whose logger is stated (aatest.metrology.logger_rails)
    _q("samples_at_logger_rails", "Samples at the logger's input-range limits", "samples", COUNT),
)}

#: a person's name of each analysis (results.json ``analysis`` key)
ANALYSES: dict[str, str] = {
    "sync": "Logger synchronisation", "reference": "Acceleration references",
    "bias": "Bias and g-sensitivity", "scale_factor": "Scale factor",
    "frf": "Frequency response", "thd": "Harmonic distortion", "snr": "Signal-to-noise ratio",
    "transfer_function": "Transfer function", "temperature": "Temperature coefficients",
    "misalignment": "Misalignment", "noise": "Noise", "drift": "Bias drift and Allan deviation",
    "diagnose": "Diagnosis",
}


#: acceleration references by the name a person reads: the public names a scale factor is
#: calibrated against and the implementation names the reference analysis compares
REFERENCE_METHODS: dict[str, str] = {
    "fit": "polynomial fit of the position", "savgol": "polynomial fit of the position",
    "table_estimate": "table estimate", "table": "table estimate",
    "central": "central difference", "central_position": "central difference of the position",
    "central_rate": "central difference of the rate",
    "five_point": "five-point difference",
    "five_point_position": "five-point difference of the position",
    "five_point_rate": "five-point difference of the rate",
    "smoothed": "smoothed position", "smooth": "smoothed position",
    "sliding_mode": "sliding-mode differentiator", "levant": "sliding-mode differentiator",
}
#: probability distributions of budget rows by the name a person reads
DISTRIBUTIONS: dict[str, str] = {"normal": "normal", "rectangular": "rectangular",
                                 "cosine_error": "cosine error"}


def reference_name(key: str) -> str:
    """A person's name of an acceleration reference (its key when it is not a known one)."""
    return REFERENCE_METHODS.get(key, key.replace("_", " "))


def quantity(key: str) -> Quantity:
    """The entry of ``key``; an unknown key (a third-party quantity) reads as its own words."""
    return QUANTITIES.get(key) or Quantity(key, key.replace("_", " ").capitalize(), "", 6)


def analysis_name(key: str) -> str:
    """A person's name of an analysis; a third-party one reads as its own words."""
    return ANALYSES.get(key) or key.replace("_", " ").capitalize()
