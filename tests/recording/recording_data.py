"""Synthetic two-logger step data for the recording, importer and exporter tests.

Built with NumPy only (no twin), physically consistent: a coherent sine on one table axis
logged at 2 kHz with its 100 Hz sync pulse and latch times, and a DAQ on its own, slightly
fast clock that starts 0.25 s earlier, with a linear sensor and a temperature channel.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from aatest.engine.logs import DAQ, TABLE, TABLE_CHANNELS, SampledLog
from aatest.engine.steps import PlannedStep
from aatest.recording.dataset import Dataset, SensorInfo, StepData

RATE_HZ = 2000.0
SENSOR = SensorInfo(channel="v_sz", axis="I", nominal_bias_v=2.5, nominal_scale_v_per_dps2=0.004014)
DAQ_LEAD_S = 0.25
DRIFT_PPM = 12.0


def sine_step(step_id: str = "s01", samples: int = 8192, axis: str = "inner") -> PlannedStep:
    """A coherent sine step (8 cycles in the record), 100 °/s² peak."""
    freq_hz = 8 * RATE_HZ / samples
    accel_dps2 = 100.0
    return PlannedStep(
        id=step_id, kind="sine", axis=axis, samples=samples, sample_rate_hz=RATE_HZ,
        duration_s=samples / RATE_HZ, frequency_hz=freq_hz, cycles=8, accel_dps2=accel_dps2,
        amplitude_deg=accel_dps2 / (2 * np.pi * freq_hz) ** 2, outer_deg=30.0,
    )


def table_log(step: PlannedStep, rng: np.random.Generator, latch: bool = True) -> SampledLog:
    """Table log of ``step``: its axis follows the sine, the other axis rests at its angle."""
    n = step.samples
    t = np.arange(n) / RATE_HZ
    w = 2 * np.pi * (step.frequency_hz or 0.0)
    amp = step.amplitude_deg or 0.0
    moving = {"position_deg": amp * np.sin(w * t), "rate_dps": amp * w * np.cos(w * t),
              "accel_dps2": -amp * w**2 * np.sin(w * t)}
    rest = {"position_deg": np.full(n, step.outer_deg if step.axis == "inner" else step.inner_deg),
            "rate_dps": np.zeros(n), "accel_dps2": np.zeros(n)}
    me, other = ("inner", "outer") if step.axis == "inner" else ("outer", "inner")
    channels = {f"{me}_{k}": v + rng.normal(0, 1e-4, n) for k, v in moving.items()}
    channels.update({f"{other}_{k}": v for k, v in rest.items()})
    channels["inner_feedback_deg"] = channels["inner_position_deg"] + rng.normal(0, 1e-5, n)
    channels["outer_feedback_deg"] = channels["outer_position_deg"] + rng.normal(0, 1e-5, n)
    channels["sync_pulse"] = ((np.arange(n) // 10) % 2 == 0).astype(np.uint8)
    if latch:
        channels["fp_latch_s"] = rng.uniform(0, 1 / RATE_HZ, n)
    units = {k: v for k, v in TABLE_CHANNELS.items() if k in channels}
    return SampledLog(TABLE, RATE_HZ, t, channels, units)


def daq_log(step: PlannedStep, table: SampledLog, rng: np.random.Generator) -> SampledLog:
    """DAQ log: own clock (12 ppm fast), starts 0.25 s before the table, sensor v_sz."""
    lead = int(DAQ_LEAD_S * RATE_HZ)
    n = len(table) + lead + 100
    t = np.arange(n) / (RATE_HZ * (1 + DRIFT_PPM * 1e-6))
    accel_key = f"{step.axis}_accel_dps2"
    accel = np.interp(t - DAQ_LEAD_S, table.time_s, table[accel_key], left=0.0, right=0.0)
    volts = SENSOR.nominal_bias_v + SENSOR.nominal_scale_v_per_dps2 * accel
    channels = {
        "sync_pulse": ((np.arange(n) // 10) % 2 == 0).astype(np.uint8),
        "trigger": (np.arange(n) >= lead).astype(np.uint8),
        "v_sz": volts + rng.normal(0, 3e-3, n),
        "temperature_c": 25.0 + rng.normal(0, 0.01, n),
    }
    return SampledLog(DAQ, RATE_HZ, t, channels, {"v_sz": "V", "temperature_c": "degC"})


def step_logs(step: PlannedStep, seed: int, latch: bool = True) -> tuple[SampledLog, SampledLog]:
    """(table, DAQ) logs of one step, seeded."""
    rng = np.random.default_rng(seed)
    table = table_log(step, rng, latch)
    return table, daq_log(step, table, rng)


def run_meta(steps: list[PlannedStep]) -> dict[str, object]:
    """Run metadata as the runner writes it."""
    return {
        "procedure": "unit-test", "procedure_text": "procedure: unit-test\n",
        "procedure_sha256": "0" * 64, "rig": {"turntable": "sim"}, "plugin_versions": {},
        "seed": 7, "sensors": [vars(SENSOR)], "plan": [s.model_dump(mode="json") for s in steps],
        "started_utc": "2026-11-21T06:00:00+00:00",
    }


def one_step_dataset(procedure: str, step: PlannedStep, table: SampledLog, daq: SampledLog
                     ) -> tuple[Dataset, dict[str, object]]:
    """A dataset of one sine ``step`` with its two logs, and the dataset.yaml keys that
    describe it (for the logger-file writers)."""
    dataset = Dataset(procedure=procedure, sample_rate_hz=RATE_HZ, sensors=(SENSOR,),
                      steps=(StepData(step, table, daq),), source=Path("."))
    manifest = {"procedure": procedure, "sample_rate_hz": RATE_HZ,
                "sensors": [SENSOR.model_dump(mode="json")],
                "steps": [{"id": step.id, "kind": "sine", "axis": step.axis,
                           "frequency_hz": step.frequency_hz, "accel_dps2": step.accel_dps2,
                           "outer_deg": step.outer_deg}]}
    return dataset, manifest
