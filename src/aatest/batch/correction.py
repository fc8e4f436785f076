"""A correction of a reference standard found out of tolerance, and its application to data.

ISO/IEC 17025 §7.10: when a reference standard turns out to have been wrong, the lab finds the
calibrations that relied on it and re-evaluates them with the corrected reference. The
correction file (YAML, schema :class:`ReferenceCorrection`, docs/batch.md) states what was
found, as the reference's recalibration certificate states it:

- an encoder (or rate reference) whose reading was ``(1 + e)`` times the true angle: every
  table channel derived from it (position, rate, acceleration, raw feedback) was ``(1 + e)``
  times too large;
- a data logger whose reading was ``(1 + g)`` times the true voltage (and ``offset_v`` above
  it): every sensor voltage channel it recorded was ``(1 + g)·V + offset_v``.

:func:`corrected` undoes exactly that on a :class:`~aatest.recording.dataset.Dataset` as each
step is decoded (the recording on disk is never changed), so the unchanged analyses then
compute what the run would have given with a correct reference.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Container, Iterator
from datetime import date
from pathlib import Path

from pydantic import BaseModel, ConfigDict, Field, model_validator

from aatest.engine.logs import SampledLog
from aatest.recording.dataset import Dataset, LazySteps, StepData

#: table channels an angle encoder's scale error scales (by the naming of ``TABLE_CHANNELS``)
ENCODER_SUFFIXES = ("_position_deg", "_rate_dps", "_accel_dps2", "_feedback_deg")
#: reference kinds each correction applies to (``aatest references add --kind``)
ENCODER_KINDS = frozenset({"encoder", "rate-reference"})
LOGGER_KINDS = frozenset({"data-logger"})


class ReferenceCorrection(BaseModel):
    """What the recalibration of a reference standard found (``records impact --correction``).

    Errors are stated as the reference's reading relative to the truth: ``+500`` ppm means it
    read 500 ppm high. At least one error must be given.
    """

    model_config = ConfigDict(extra="forbid", frozen=True)
    reference: str = Field(min_length=1, max_length=64,
                           description="identifier of the reference in the register")
    found_on: date = Field(description="when the error was found (the recalibration)")
    reason: str = Field(min_length=1, description="what was found, for the impact report")
    encoder_scale_error_ppm: float | None = Field(
        None, gt=-1e5, lt=1e5, description="encoder read (1 + e) × the true angle; e in ppm")
    logger_gain_error_ppm: float | None = Field(
        None, gt=-1e5, lt=1e5, description="logger read (1 + g) × the true voltage; g in ppm")
    logger_offset_v: float = Field(0.0, description="logger read this much above the truth, V")
    channels: tuple[str, ...] | None = Field(
        None, description="logger channels affected (default: every sensor channel v_*)")

    @model_validator(mode="after")
    def _states_an_error(self) -> ReferenceCorrection:
        if self.encoder_scale_error_ppm is None and self.logger_gain_error_ppm is None \
                and self.logger_offset_v == 0.0:
            raise ValueError("state at least one of encoder_scale_error_ppm, "
                             "logger_gain_error_ppm, logger_offset_v")
        return self

    def touches_logger(self) -> bool:
        """Whether the correction changes logger voltages."""
        return self.logger_gain_error_ppm is not None or self.logger_offset_v != 0.0

    def fits_kind(self, kind: str) -> str | None:
        """Why this correction cannot apply to a reference of ``kind`` (None: it can)."""
        if self.encoder_scale_error_ppm is not None and kind not in ENCODER_KINDS:
            return f"an encoder scale error is stated, but {self.reference} is of kind {kind}"
        if self.touches_logger() and kind not in LOGGER_KINDS:
            return f"a logger gain/offset error is stated, but {self.reference} is of kind {kind}"
        return None


def load_correction(path: Path) -> ReferenceCorrection:
    """Read and validate a correction file (YAML, loaded safely).

    Raises
    ------
    InputError
        The file is unreadable or invalid; the message is ``FILE:LINE:COLUMN: field: …``.
    """
    from aatest.positioned_yaml import load_model_file

    return load_model_file(path, ReferenceCorrection)


def _scaled(log: SampledLog, names: Container[str], factor: float, offset: float) -> SampledLog:
    """``log`` with ``(value − offset) / factor`` on the channels in ``names``; the integer
    quantisation of those channels is carried along (``(code·q + o − offset)/factor``)."""
    chosen = [n for n in log.channels if n in names]
    if not chosen:
        return log
    channels = dict(log.channels)
    quanta = dict(log.quantisation)
    for name in chosen:
        channels[name] = (log.channels[name] - offset) / factor
        if name in quanta:
            quantum, low = quanta[name]
            quanta[name] = (quantum / factor, (low - offset) / factor)
    return SampledLog(log.source, log.sample_rate_hz, log.time_s, channels, log.units, quanta)


@dataclasses.dataclass(frozen=True)
class _Undo:
    """The inverse of a :class:`ReferenceCorrection` on one log."""

    correction: ReferenceCorrection

    def log(self, log: SampledLog) -> SampledLog:
        fix = self.correction
        if log.source == "table" and fix.encoder_scale_error_ppm is not None:
            encoded = [n for n in log.channels if n.endswith(ENCODER_SUFFIXES)]
            log = _scaled(log, encoded, 1.0 + fix.encoder_scale_error_ppm * 1e-6, 0.0)
        if log.source == "daq" and fix.touches_logger():
            logged = fix.channels if fix.channels is not None else log.sensor_channels()
            gain = 1.0 + (fix.logger_gain_error_ppm or 0.0) * 1e-6
            log = _scaled(log, logged, gain, fix.logger_offset_v)
        return log

    def step(self, step: StepData) -> StepData:
        return StepData(step.step, self.log(step.table), self.log(step.daq))


def corrected(dataset: Dataset, correction: ReferenceCorrection | None) -> Dataset:
    """``dataset`` as a correct reference would have recorded it (itself when no correction).

    A recording's steps stay lazy: each log is corrected as it is decoded, so memory still
    holds one step at a time.
    """
    if correction is None:
        return dataset
    undo = _Undo(correction)
    steps = dataset.steps
    if isinstance(steps, LazySteps):
        load, pieces = steps._load, steps._pieces

        def load_fixed(i: int, source: str, channels: Container[str] | None) -> SampledLog:
            return undo.log(load(i, source, channels))

        def pieces_fixed(i: int, source: str, channels: Container[str] | None
                         ) -> Iterator[SampledLog]:
            assert pieces is not None
            return (undo.log(p) for p in pieces(i, source, channels))

        fixed: LazySteps | tuple[StepData, ...] = LazySteps(
            steps.planned, load_fixed, steps._samples,
            pieces_fixed if pieces is not None else None)
    else:
        fixed = tuple(undo.step(s) for s in steps)
    return dataclasses.replace(dataset, steps=fixed)
