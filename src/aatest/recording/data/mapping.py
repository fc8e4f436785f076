"""The mapping file of a logger's data files (TDMS, MF4): which channel is which, in what unit.

A lab's logger names its channels as the lab wired them (``AI0``, ``Table/Position``); aatest
needs the table's position, rate and acceleration, the freeze pulse on both sides, the DAQ's
trigger and each sensor's volts. ``mapping.yaml`` says where each one is and how its stored
numbers become aatest's units: ``value = (gain·raw + offset)`` in the stated ``unit``, then the
unit's conversion to the canonical one (rad → °, mV → V, K → °C ...). It carries the same
per-step metadata and sensor list as ``dataset.yaml`` (docs/interfaces.md §3), with each step's
``table``/``daq`` naming a *group* of the file (a TDMS group, an MF4 channel group's acquisition
name or its index) instead of a CSV file.

Units are required where a quantity has more than one plausible unit: a mapping that says
nothing about radians vs degrees is the error this file exists to prevent. Every problem is
reported as ``FILE:LINE:COLUMN`` (the positioned YAML loader of
:mod:`aatest.positioned_yaml`).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Literal, get_args

from pydantic import Field, model_validator

from aatest.engine.errors import ProblemsError
from aatest.positioned_yaml import parse_yaml, read_text, validate_tree
from aatest.recording.data.importer import DatasetFileError, DatasetManifest, StepEntry, _Strict

MAPPING = "mapping.yaml"
FORMATS = ("tdms", "mf4")

#: unit → (factor, shift): canonical value = factor·value + shift
UNIT_CONVERSIONS: dict[str, tuple[float, float]] = {
    "deg": (1.0, 0.0), "rad": (180.0 / math.pi, 0.0), "arcsec": (1.0 / 3600.0, 0.0),
    "deg/s": (1.0, 0.0), "rad/s": (180.0 / math.pi, 0.0), "rpm": (6.0, 0.0),
    "deg/s^2": (1.0, 0.0), "rad/s^2": (180.0 / math.pi, 0.0),
    "V": (1.0, 0.0), "mV": (1e-3, 0.0),
    "degC": (1.0, 0.0), "K": (1.0, -273.15),
    "s": (1.0, 0.0), "ms": (1e-3, 0.0), "us": (1e-6, 0.0),
    "1": (1.0, 0.0),
}
#: how files commonly spell the units above (a file's own unit is compared after this)
UNIT_SPELLINGS = {"°": "deg", "degree": "deg", "degrees": "deg", "°/s": "deg/s",
                  "°/s²": "deg/s^2", "°/s^2": "deg/s^2", "deg/s²": "deg/s^2",
                  "rad/s²": "rad/s^2", "°C": "degC", "volt": "V", "volts": "V", "sec": "s",
                  "µs": "us"}


class ChannelMap(_Strict):
    """One mapped channel: its name in the file's group, and the scaling of its numbers."""

    channel: str = Field(min_length=1)
    #: value in ``unit`` = gain·stored + offset
    gain: float = Field(1.0, allow_inf_nan=False)
    offset: float = Field(0.0, allow_inf_nan=False)
    #: false: a group without this channel is not an error (the channel is then filled)
    required: bool = True

    def scaling(self) -> tuple[float, float]:
        """(factor, shift) taking stored numbers to the canonical unit in one multiply-add.

        Returns
        -------
        tuple of float
            The factor (canonical unit per stored unit: dimensionless between like units,
            e.g. 57.3 °/rad) and the shift (in the canonical unit, e.g. −273.15 °C).
        """
        factor, shift = UNIT_CONVERSIONS[getattr(self, "unit", "1")]
        return self.gain * factor, self.offset * factor + shift

    @classmethod
    def units(cls) -> tuple[str, ...]:
        """The units this kind of channel may be stated in."""
        field = cls.model_fields.get("unit")
        return get_args(field.annotation) if field is not None else ("1",)


class AngleChannel(ChannelMap):
    """An angle (table position, encoder feedback); canonical unit °."""

    unit: Literal["deg", "rad", "arcsec"]


class RateChannel(ChannelMap):
    """An angular rate; canonical unit °/s."""

    unit: Literal["deg/s", "rad/s", "rpm"]


class AccelChannel(ChannelMap):
    """An angular acceleration; canonical unit °/s²."""

    unit: Literal["deg/s^2", "rad/s^2"]


class VoltChannel(ChannelMap):
    """A sensor output; canonical unit V."""

    unit: Literal["V", "mV"]


class TemperatureChannel(ChannelMap):
    """A temperature; canonical unit °C."""

    unit: Literal["degC", "K"]


class TimeChannel(ChannelMap):
    """Time stamps or latch times; canonical unit s."""

    unit: Literal["s", "ms", "us"]


class PulseChannel(ChannelMap):
    """A 0/1 line (freeze pulse, trigger): stored as 0/1, or as volts cut at ``threshold``."""

    threshold: float | None = Field(None, allow_inf_nan=False)

    @model_validator(mode="after")
    def _no_scaling(self) -> PulseChannel:
        if (self.gain, self.offset) != (1.0, 0.0):
            raise ValueError("a pulse line takes a threshold, not gain/offset")
        return self


class TableExtras(_Strict):
    """Further table channels under their canonical names (the axis at rest, raw feedback)."""

    inner_position_deg: AngleChannel | None = None
    inner_rate_dps: RateChannel | None = None
    inner_accel_dps2: AccelChannel | None = None
    outer_position_deg: AngleChannel | None = None
    outer_rate_dps: RateChannel | None = None
    outer_accel_dps2: AccelChannel | None = None
    inner_feedback_deg: AngleChannel | None = None
    outer_feedback_deg: AngleChannel | None = None


class TableMap(_Strict):
    """The table controller's channels, found in every step's ``table`` group.

    ``position``/``rate``/``accel`` are the moving axis (as the CSV's ``position_deg`` ...).
    ``time`` absent: the file's own time base (a TDMS waveform's ``wf_start_offset`` and
    ``wf_increment``, an MF4 group's master channel).
    """

    time: TimeChannel | None = None
    position: AngleChannel
    rate: RateChannel
    accel: AccelChannel
    freeze_pulse: PulseChannel
    fp_latch_s: TimeChannel | None = None
    channels: TableExtras = TableExtras()


class DaqMap(_Strict):
    """The sensor logger's channels, found in every step's ``daq`` group.

    ``sensors`` maps a sensor ``channel`` of the sensor list to its logger channel; a sensor
    not listed is read from the channel of its own name, in volts.
    """

    time: TimeChannel | None = None
    freeze_pulse: PulseChannel
    trigger: PulseChannel
    temperature: TemperatureChannel | None = None
    sensors: dict[str, VoltChannel] = Field(default_factory=dict)


class MappedStep(StepEntry):
    """A step: the dataset.yaml step, its two groups, and (optionally) its own file."""

    table: str | int  # type: ignore[assignment]  # a group: a name, or an MF4 group index
    daq: str | int  # type: ignore[assignment]
    file: str | None = Field(None, min_length=1)


class LoggerMapping(DatasetManifest):
    """``mapping.yaml``: the dataset.yaml keys plus the format, file and channel mapping."""

    format: Literal["tdms", "mf4"]
    file: str | None = Field(None, min_length=1)
    table: TableMap
    daq: DaqMap
    steps: list[MappedStep] = Field(min_length=1)  # type: ignore[assignment]

    def sensor_map(self) -> dict[str, VoltChannel]:
        """Every sensor channel's mapping (a sensor not listed: its own name, volts)."""
        return {s.channel: self.daq.sensors.get(s.channel) or VoltChannel(channel=s.channel,
                                                                          unit="V")
                for s in self.sensors}


def load_mapping(path: Path) -> tuple[LoggerMapping, Any]:
    """Parse and validate ``mapping.yaml``; return the model and the positioned YAML tree."""
    try:
        tree, data = parse_yaml(read_text(path), str(path))
        return validate_tree(LoggerMapping, tree, data, str(path)), tree
    except ProblemsError as exc:
        raise DatasetFileError(exc.problems) from exc


def canonical_unit(spelled: str) -> str:
    """A file's unit string in this module's spelling (unknown spellings are kept)."""
    text = spelled.strip()
    return UNIT_SPELLINGS.get(text, text)
