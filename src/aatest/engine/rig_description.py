"""The rig's instruments: their stated accuracies and calibration traceability (``--rig`` YAML).

The uncertainty budgets (:mod:`aatest.metrology.uncertainty`) take every Type B component they
cannot measure from here: the encoder's accuracy and resolution, the sensor logger's offset
and gain accuracy and resolution, the thermometer, the table's wobble and orthogonality, the
mounting accuracy and the reference temperature. Each instrument may name the calibration
certificate that makes it traceable; the results carry those (``metadata.traceability``) so
the certificate can state them. Every field has a stated default, the documented rig of
docs/method.md §1.2 and §2; a budget row built on a default says so in its basis.

Example (``--rig rig.yaml``)::

    turntable: {plugin: sim}
    instruments:
      encoder: {accuracy_arcsec: 1.0, cert_id: ENC-77, cert_date: 2026-01-12, lab: PTB}
      logger: {offset_accuracy_v: 0.001, gain_accuracy_pct: 0.1, bits: 16,
               range_v: [-10, 10], cert_id: LOG-123, cert_date: 2026-03-01}
"""

from __future__ import annotations

import datetime as dt
import math

from pydantic import BaseModel, ConfigDict, Field, model_validator


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class Traceable(_Strict):
    """Calibration certificate of one instrument (empty: not stated)."""

    cert_id: str = Field("", description="calibration certificate number")
    cert_date: dt.date | None = Field(None, description="date of that calibration")
    lab: str = Field("", description="laboratory that issued the certificate")

    def cert_text(self) -> str:
        """``cert LOG-123, 2026-03-01, PTB`` or ``no certificate stated``."""
        parts = [p for p in (self.cert_id and f"cert {self.cert_id}",
                             self.cert_date and self.cert_date.isoformat(), self.lab) if p]
        return ", ".join(parts) if parts else "no certificate stated"


class EncoderSpec(Traceable):
    """The table's angle encoder: the reference of every angle, rate and acceleration."""

    accuracy_arcsec: float = Field(1.0, ge=0, description="position accuracy bound, arcsec")
    resolution_counts_per_rev: int = Field(129_600_000, gt=0,
                                           description="counts per revolution (0.01″ steps)")
    error_cycles_per_rev: int = Field(
        360, gt=0, description="highest spatial frequency of the encoder's angle error "
        "(graduation/interpolation period), cycles per revolution: bounds how fast the error "
        "can change over a small motion")

    @property
    def resolution_arcsec(self) -> float:
        """One count, in arcseconds (″; 1″ = 1/3600 deg)."""
        return 360.0 * 3600.0 / self.resolution_counts_per_rev


class LoggerSpec(Traceable):
    """The sensor logger (SDAS): analogue input accuracy and converter resolution."""

    offset_accuracy_v: float = Field(0.001, ge=0, description="zero offset bound, V")
    gain_accuracy_pct: float = Field(0.1, ge=0, description="gain error bound, % of reading")
    bits: int = Field(16, ge=4, le=32, description="converter resolution, bits")
    range_v: tuple[float, float] = Field((-10.0, 10.0), description="input range, V")
    timing_accuracy_us: float = Field(
        10.0, ge=0, description="bound of the logger's sampling instant against the table's "
        "freeze-pulse latch (latch latency, channel skew), µs: a constant time offset the sync "
        "fit cannot see")

    @model_validator(mode="after")
    def _ordered(self) -> LoggerSpec:
        if not self.range_v[1] > self.range_v[0]:
            raise ValueError("range_v must be [low, high] with high > low")
        return self

    @property
    def step_v(self) -> float:
        """One converter step q (16 bits over ±10 V: 305 µV), V."""
        return float(self.range_v[1] - self.range_v[0]) / float(2**self.bits)

    @property
    def resolution_u_v(self) -> float:
        """Standard uncertainty of one quantised reading, q/√12, V."""
        return self.step_v / math.sqrt(12.0)


class ThermometerSpec(Traceable):
    """The thermometer whose readings are logged beside the sensor."""

    accuracy_c: float = Field(0.2, ge=0, description="reading accuracy bound, °C")


class TableGeometry(_Strict):
    """Geometric errors of the table axes (bounds)."""

    wobble_arcsec: float = Field(2.0, ge=0, description="inner-axis wobble bound, arcsec")
    orthogonality_arcsec: float = Field(3.0, ge=0, description="axis orthogonality bound, arcsec")


class LabSpec(_Strict):
    """The laboratory environment when no temperature is logged."""

    reference_temperature_c: float = Field(25.0, description="reference temperature, °C")
    temperature_tolerance_c: float = Field(3.0, ge=0,
                                           description="lab temperature bound about it, °C")


class Instruments(_Strict):
    """Stated accuracies and traceability of the rig's instruments (``instruments:`` block)."""

    encoder: EncoderSpec = EncoderSpec()
    logger: LoggerSpec = LoggerSpec()
    thermometer: ThermometerSpec = ThermometerSpec()
    table: TableGeometry = TableGeometry()
    lab: LabSpec = LabSpec()
    mounting_accuracy_deg: float = Field(0.3, ge=0,
                                         description="sensor mounting (seat + block) bound, °")

    def traceability(self) -> dict[str, dict[str, str]]:
        """Instrument → ``{cert_id, cert_date, lab, accuracy}`` for ``metadata.traceability``."""
        def entry(spec: Traceable, accuracy: str) -> dict[str, str]:
            return {"cert_id": spec.cert_id or "not stated",
                    "cert_date": spec.cert_date.isoformat() if spec.cert_date else "not stated",
                    "lab": spec.lab or "not stated", "accuracy": accuracy}

        lg = self.logger
        return {
            "encoder": entry(self.encoder, f"±{self.encoder.accuracy_arcsec:g}″, "
                             f"{self.encoder.resolution_counts_per_rev} counts/rev"),
            "logger": entry(lg, f"offset ±{lg.offset_accuracy_v * 1e3:g} mV, gain "
                            f"±{lg.gain_accuracy_pct:g} %, {lg.bits} bit over "
                            f"{lg.range_v[0]:g}…{lg.range_v[1]:g} V"),
            "thermometer": entry(self.thermometer, f"±{self.thermometer.accuracy_c:g} °C"),
        }
