"""What a turntable plugin declares about its instruments (``Turntable.capabilities()``).

A module of its own (re-exported by :mod:`aatest.engine.interfaces`) because the recording's
import and export read and write the declaration too, and must not import the plugin
interfaces (which import the recording).
"""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field


class TableCapabilities(BaseModel):
    """What a turntable declares about its instruments (``Turntable.capabilities()``).

    None means *not declared*; the engine then says so wherever the value matters (the
    uncertainty budget names the missing declaration in the basis of the row that falls back
    to a stated default). The envelope (:class:`TableEnvelope`) declares the limits, the axes
    present, the log rate and the log length. ``model`` and ``serial`` may be None before
    :meth:`Turntable.start` and are asked for again after it (identification).
    """

    model_config = ConfigDict(frozen=True, extra="forbid")
    encoder_resolution_counts_per_rev: int | None = Field(
        None, gt=0, description="encoder counts per revolution (2**24: 0.077″ per count)")
    encoder_accuracy_arcsec: float | None = Field(
        None, ge=0, description="position accuracy bound of the encoder, arcsec")
    trigger_input: bool | None = Field(
        None, description="the table log can be started by the DAQ's trigger line")
    pulse_latch: bool | None = Field(
        None, description="the table latches each freeze-pulse edge to its controller clock "
        "(column fp_latch_s of its log); False: fp_latch_s is absent or NaN")
    model: str | None = Field(None, description="table model, as identified")
    serial: str | None = Field(None, description="table serial number, as identified")
