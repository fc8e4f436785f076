"""The expanded plan: concrete steps the runner executes and the recording describes.

A :class:`PlannedStep` is immutable and fully resolved (no generators, no defaults left to
guess), so the same object drives the rig, labels the recording, and tells the analyses what
was commanded. Units: degrees, seconds, °/s, °/s², °C.
"""

from __future__ import annotations

from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field

from aatest.rig_defaults import LOG_RATE_HZ

StepKind = Literal["static", "sine", "constant_rate", "chamber"]
Axis = Literal["inner", "outer", "both", "none"]
Remount = Literal["none", "sensors", "block", "both"]


class _Frozen(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid")


class Mounting(_Frozen):
    """How the sensor unit sits on the table for this step (operator-controlled)."""

    pivoted: bool = False
    remount: Remount = "none"
    scenario: str | None = Field(None, description="misalignment set label A..H")
    experiment: int | None = Field(None, description="misalignment experiment 1..6")


class PlannedStep(_Frozen):
    """One recorded (or chamber) step of a plan."""

    id: str
    kind: StepKind
    axis: Axis = "none"
    duration_s: float = Field(0.0, ge=0, description="recorded length, samples / rate")
    settle_s: float = Field(0.0, ge=0, description="time in motion before recording starts")
    sample_rate_hz: float = LOG_RATE_HZ
    samples: int = 0
    frequency_hz: float | None = None
    cycles: int | None = Field(None, description="whole cycles in the record (coherent sine)")
    amplitude_deg: float | None = None
    accel_dps2: float | None = Field(None, description="peak commanded acceleration")
    rate_dps: float | None = Field(None, description="constant rate of the moving (inner) axis")
    outer_rate_dps: float | None = Field(None, description="outer rate in coordinated motion")
    inner_deg: float = 0.0
    outer_deg: float = 0.0
    temperature_c: float | None = Field(None, description="chamber set-point in force")
    soak_s: float | None = Field(None, description="chamber stabilisation time (chamber steps)")
    stable_tolerance_c: float | None = Field(
        None, description="soak until the sensor temperature's spread over stable_window_s is "
        "at most this, °C (chamber steps; soak_s is then the window)")
    stable_window_s: float | None = Field(None, description="window of the stability test, s")
    soak_max_s: float | None = Field(None, description="longest soak until stable, s")
    motor_on: bool = True
    group: str | None = Field(None, description="test group label, e.g. 'accel-400'")
    repetition: int = 1
    mounting: Mounting = Mounting()
    prompt: str | None = Field(None, description="operator instruction shown before the step")

    @property
    def lab_duration_s(self) -> float:
        """Lab time the step occupies in s: soak, settling and the record itself."""
        soak = self.soak_max_s if self.soak_max_s is not None else (self.soak_s or 0.0)
        return soak + self.settle_s + self.duration_s

    @property
    def recorded(self) -> bool:
        """Chamber steps only change the set-point; every other kind records both loggers."""
        return self.kind != "chamber"


#: the serial of a unit nobody named (procedure without ``sensor.serial``, no ``--serial``)
UNNAMED_SERIAL = "unknown"


class SensorRef(_Frozen):
    """A device under test, resolved through the ``aatest.sensors`` plugins."""

    model: str
    serial: str = UNNAMED_SERIAL

    @property
    def named(self) -> bool:
        """Whether the unit's serial was given (a calibration of a real unit needs it)."""
        return self.serial != UNNAMED_SERIAL


class Plan(_Frozen):
    """The fully expanded procedure."""

    procedure: str
    standard: str = "IEEE-671-style"
    sensor: SensorRef
    steps: tuple[PlannedStep, ...]
    #: procedure ``analysis:`` entries as written: a name or ``{name: {options}}``
    analysis: tuple[str | dict[str, dict[str, Any]], ...] = ()
    report_template: str = "calibration-certificate"
    sign: bool = False

    def __hash__(self) -> int:
        # analysis options are dicts (unhashable); the JSON text identifies the whole plan
        return hash(self.model_dump_json())

    @property
    def lab_duration_s(self) -> float:
        """Lab time of the whole plan in s: the sum over its steps."""
        return float(sum(s.lab_duration_s for s in self.steps))

    def to_contract_json(self) -> dict[str, object]:
        """The ``aatest plan --json`` document (docs/interfaces.md §1)."""
        return {
            "procedure": self.procedure,
            "steps": [s.model_dump(mode="json") for s in self.steps],
            "lab_duration_s": self.lab_duration_s,
        }
