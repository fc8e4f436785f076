"""The rig's stated accuracies that enter every uncertainty budget (docs/method.md §1.2, §2).

The measurement models (:mod:`.measurands`), their budget rows (:mod:`.components`) and the
clock window (:mod:`.clock_window`) all read these constants; they live apart from the models
so the rows can be built without importing the models that use them.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from pydantic import BaseModel, ConfigDict, Field

from aatest.engine.rig_description import Instruments
from aatest.metrology.uncertainty.declared import Basis, declared_encoder
from aatest.metrology.uncertainty.evidence import Evidence, gather
from aatest.results import RunResults
from aatest.rig_defaults import LOG_RATE_HZ, RECORD_SAMPLES


class RigConstants(BaseModel):
    """Stated accuracies of the rig that enter every budget (docs/method.md §1.2, §2).

    Built from the run's rig description by :meth:`from_results` (the ``instruments`` block of
    ``--rig``, or of an import's ``dataset.yaml``); ``instruments_stated`` is False when the
    description stated none and the documented defaults stand in (each basis says so).
    ``evidence`` holds what the recording itself shows (motion distortion, temperatures).
    """

    model_config = ConfigDict(frozen=True, extra="forbid", arbitrary_types_allowed=True)
    position_accuracy_arcsec: float = Field(1.0, ge=0, description="table positioning, 1″ RSS")
    wobble_arcsec: float = Field(2.0, ge=0, description="inner-axis wobble bound")
    orthogonality_arcsec: float = Field(3.0, ge=0, description="inner/outer orthogonality bound")
    temperature_stability_c: float = Field(0.2, ge=0, description="± band during a record")
    thermometer_uncertainty_c: float = Field(0.1, ge=0, description="standard, per reading")
    noise_bandwidth_hz: float = Field(100.0, gt=0, description="anti-alias filter corner")
    record_samples: int = Field(RECORD_SAMPLES, gt=0,
                                description="samples per record if not stated")
    sample_rate_hz: float = Field(LOG_RATE_HZ, gt=0)
    static_record_s: float = Field(67.5, gt=0, description="static record if not stated")
    temperature_span_c: float = Field(69.0, gt=0, description="−21…48 °C if not stated")
    instruments: Instruments = Field(default_factory=Instruments)
    instruments_stated: bool = Field(False, description="the rig description stated them")
    evidence: Evidence = Field(default_factory=Evidence)
    #: encoder numbers not from the rig description: declared by the table plugin, or a
    #: default naming the missing declaration (:mod:`.declared`)
    encoder_basis: Basis = Field(default_factory=dict)

    @classmethod
    def from_results(cls, results: RunResults, data: Any = None) -> RigConstants:
        """The constants of this run: its rig description's instruments and its recording.

        Parameters
        ----------
        results
            The typed results; ``metadata.rig.instruments`` (or ``rig.instruments``) is the
            stated description.
        data
            The dataset the analyses ran on, for the measured components (None: none).
        """
        stated = _stated_instruments(results)
        instruments = Instruments.model_validate(stated) if stated is not None else Instruments()
        instruments, encoder_basis = declared_encoder(results, stated, instruments)
        return cls(encoder_basis=encoder_basis,
                   position_accuracy_arcsec=instruments.encoder.accuracy_arcsec,
                   wobble_arcsec=instruments.table.wobble_arcsec,
                   orthogonality_arcsec=instruments.table.orthogonality_arcsec,
                   thermometer_uncertainty_c=instruments.thermometer.accuracy_c / math.sqrt(3.0),
                   instruments=instruments, instruments_stated=stated is not None,
                   evidence=gather(data))

    def encoder_note(self, field: str, what: str, cert: str = "") -> str:
        """The basis of an encoder row: the rig description's, the declaring plugin's, or a
        stated default naming the missing declaration (:mod:`.declared`)."""
        kind, text = self.encoder_basis.get(field, ("", ""))
        if kind == "declared":
            return f"{text}: {what}"
        if kind == "default":
            return f"stated default: {what} ({text})"
        return self.source(what, cert)

    def source(self, what: str, cert: str = "") -> str:
        """``rig description: <what> (<cert>)``, or ``stated default: <what>`` without one."""
        if self.instruments_stated:
            return f"rig description: {what}" + (f" ({cert})" if cert else "")
        return f"stated default: {what} (the rig description states none)"


def _stated_instruments(results: RunResults) -> Mapping[str, Any] | None:
    """The rig description's ``instruments`` block as recorded with the run, or None.

    The rig description is the user's own YAML (``--rig``), recorded as written: a free-form
    document, validated here by :class:`Instruments`.
    """
    for rig in (results.metadata.recorded("rig"), results.rig):
        if isinstance(rig, Mapping) and isinstance(rig.get("instruments"), Mapping):
            return rig["instruments"]  # type: ignore[no-any-return]
    return None
