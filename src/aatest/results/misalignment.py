"""``analysis.misalignment``: cross-axis ratios and misalignment (method §4.5, contract §5)."""

from __future__ import annotations

from typing import ClassVar

from pydantic import Field

from aatest.results._fields import ComplexPair, Real
from aatest.results.base import DATASHEET_FLAGS, Certified, ResultModel


class SetSensor(ResultModel):
    """Published method, one sensor in one set."""

    #: the analysis' own pass/fail flags of schema 1; verdicts are the engine's
    retired_keys: ClassVar[frozenset[str]] = DATASHEET_FLAGS

    cross_ratio_x: Real
    cross_ratio_y: Real
    delta_A: ComplexPair  # noqa: N815 - the published method's symbol, a results.json key
    delta_e_deg: Real
    A_z: ComplexPair


class ScenarioSensor(Certified):
    """Published method, one sensor in one scenario (certified: ``delta_deg``)."""

    delta_deg: Real
    A_S: ComplexPair


class MatrixScenarioSensor(Certified):
    """Sensitivity-matrix estimate of one sensor in one scenario (certified: the angle)."""

    #: the analysis' own pass/fail flags of schema 1; verdicts are the engine's
    retired_keys: ClassVar[frozenset[str]] = DATASHEET_FLAGS

    sensor_tilt_x_deg: Real
    sensor_tilt_y_deg: Real
    u_sensor_tilt_deg: list[Real]
    sensor_angle_deg: Real
    azimuth_deg: Real
    mounting_tilt_deg: list[Real]
    u_mounting_tilt_deg: list[Real]
    repetitions: int


class MatrixSet(ResultModel):
    """Mean complex 3×3 sensitivity matrix of one set (V per °/s² along P, O, I)."""

    re: list[list[Real]]
    im: list[list[Real]]
    repetitions: int
    pivoted: bool


class MatrixEstimate(ResultModel):
    """Our least-squares estimator: per scenario and channel, and the matrices per set."""

    scenarios: dict[str, dict[str, MatrixScenarioSensor]] = Field(default_factory=dict)
    sets: dict[str, MatrixSet] = Field(default_factory=dict)
    columns: list[str] = Field(default_factory=list)
    rows: list[str] = Field(default_factory=list)


class MisalignmentResult(ResultModel):
    """Set → sensor (SZ/SY/SX) and scenario → sensor, plus the matrix estimate."""

    sets: dict[str, dict[str, SetSensor]] = Field(default_factory=dict)
    scenarios: dict[str, dict[str, ScenarioSensor]] = Field(default_factory=dict)
    matrix: MatrixEstimate | None = None
