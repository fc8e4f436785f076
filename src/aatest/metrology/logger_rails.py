"""Whether the sensor logger clipped: each sensor channel's record judged against its rails.

Why a verdict of its own: a logger whose input range is too small for the sensor output holds
the peaks at its extreme code, and every analysis of that record is wrong without any error —
a clipped sine gives a low scale factor that may still pass its limit. The recording notes per
step and sensor channel the least and the largest value and how many samples hold each
(:mod:`aatest.recording.extremes`); here an extreme within the logger's stated accuracy of a
rail of its input range is a rail, and every sample at it counts as clipped. The verdict's limit
is 0 samples (``limit_source`` ``logger``); it is judged on every run whose logger is stated,
whatever ``acceptance.judge`` lists, because it says whether the other verdicts mean anything.

Which converter: the rig description's ``instruments.logger`` recorded with the data, else the
data's rig model. Otherwise the default logger (±10 V, 16 bit) is what a simulated logger
quantised with, so a run on the twin's logger is judged against it — unless the twin was given
a model file of its own, whose converter the run metadata does not hold; for a real logger the
default is an assumption, not a statement. Either run gets no rail verdict rather than one
judged against a range the logger may not have.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any

from aatest.engine.rig_description import LoggerSpec
from aatest.engine.simulation import metadata_of, simulated_parts
from aatest.recording import extremes
from aatest.results import RunResults
from aatest.results.root import ChannelExtremes, StepSummary

#: the judged quantity (:data:`aatest.results.quantities.QUANTITIES`)
QUANTITY = "samples_at_logger_rails"
#: where the converter comes from when the data state none (see :func:`converter_of`)
DEFAULT_SOURCE = "stated default (the data state no logger)"


def converter_of(metadata: Mapping[str, Any]) -> tuple[LoggerSpec, str]:
    """(converter, where it is stated) of the sensor logger a run's metadata name.

    The rig description's ``instruments.logger`` comes first (the one source the uncertainty
    budget's resolution row reads too); a simulated run's rig model states the converter it
    quantised with (``daq.adc_bits``, ``daq.adc_range_v``); otherwise the stated default logger
    (:class:`~aatest.engine.rig_description.LoggerSpec`, ±10 V / 16 bit) and
    :data:`DEFAULT_SOURCE`.
    """
    rig = metadata.get("rig")
    instruments = rig.get("instruments") if isinstance(rig, Mapping) else None
    if isinstance(instruments, Mapping) and isinstance(instruments.get("logger"), Mapping):
        return LoggerSpec.model_validate(instruments["logger"]), "rig description"
    model = metadata.get("model")
    daq = model.get("daq") if isinstance(model, Mapping) else None
    if isinstance(daq, Mapping) and "adc_bits" in daq and "adc_range_v" in daq:
        return (LoggerSpec(bits=daq["adc_bits"], range_v=tuple(daq["adc_range_v"])),
                "the data's rig model")
    return LoggerSpec(), DEFAULT_SOURCE


def twin_logger_is_default(metadata: Mapping[str, Any]) -> bool:
    """Whether the run's logger is the twin's own, with the default converter: a simulated
    DAQ without a model file of its own (a model file states its own converter, which the run
    metadata does not hold)."""
    rig = metadata.get("rig")
    daq = rig.get("daq") if isinstance(rig, Mapping) else None
    own_model = isinstance(daq, Mapping) and bool(daq.get("model"))
    return not own_model and any(p.startswith("daq:") for p in simulated_parts(metadata))


def rail_tolerance_v(logger: LoggerSpec, rail_v: float) -> float:
    """How far from ``rail_v`` a logged value still is that rail, V: one converter step plus
    the logger's stated offset and gain accuracy there (a logger that corrects its readings
    moves its extreme code by up to that much)."""
    return (logger.step_v + logger.offset_accuracy_v
            + logger.gain_accuracy_pct / 100.0 * abs(rail_v))


def samples_at_rails(step: ChannelExtremes, logger: LoggerSpec) -> int:
    """Samples of one channel's step at a rail of the logger's input range (0: none)."""
    low_v, high_v = logger.range_v
    count = 0
    if step.least_v <= low_v + rail_tolerance_v(logger, low_v):
        count += step.samples_at_least
    if step.largest_v >= high_v - rail_tolerance_v(logger, high_v):
        count += step.samples_at_largest
    return count


def noted_at_rails(noted: extremes.Extremes, logger: LoggerSpec) -> int:
    """:func:`samples_at_rails` of a channel's extremes as a step record notes them."""
    return samples_at_rails(ChannelExtremes.model_validate(ChannelExtremes.fields_of(noted)),
                            logger)


def clipped_samples(steps: Iterable[StepSummary], channel: str, logger: LoggerSpec
                    ) -> int | None:
    """Samples of one channel at the rails over the run; None when no step's recording noted
    the channel's extremes."""
    noted = [s.daq_extremes[channel] for s in steps
             if s.daq_extremes is not None and channel in s.daq_extremes]
    return sum(samples_at_rails(e, logger) for e in noted) if noted else None


def clipped_channels(results: RunResults, channels: Iterable[str]) -> dict[str, int]:
    """Sensor channel → samples at the stated logger's rails over the run (see the module
    docstring); empty when the run states no logger or its recording noted nothing."""
    metadata = metadata_of(results)
    logger, source = converter_of(metadata)
    if source == DEFAULT_SOURCE and not twin_logger_is_default(metadata):
        return {}
    counts = {ch: clipped_samples(results.steps, ch, logger) for ch in channels}
    return {ch: n for ch, n in counts.items() if n is not None}
