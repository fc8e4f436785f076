"""Step builders for the twin tests (imported by name: tests have no packages)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from ruamel.yaml import YAML

from aatest.engine.steps import PlannedStep
from aatest.twin.model import RigModel, load_rig_model, model_document
from aatest.twin.step_setup import SimulatedStep

FS_HZ = 2000.0


def sine_step(frequency_hz: float, accel_dps2: float, samples: int = 16384, axis: str = "inner",
              **extra: object) -> PlannedStep:
    """A coherent sine step (frequency snapped to whole cycles in the record)."""
    cycles = max(1, round(frequency_hz * samples / FS_HZ))
    f = cycles * FS_HZ / samples
    return PlannedStep(id=extra.pop("id", f"sine-{f:.3f}"), kind="sine", axis=axis,  # type: ignore[arg-type]
                       duration_s=samples / FS_HZ, settle_s=1.0, samples=samples,
                       frequency_hz=f, cycles=cycles, accel_dps2=accel_dps2, **extra)


def static_step(samples: int = 16384, **extra: object) -> PlannedStep:
    return PlannedStep(id=str(extra.pop("id", "static")), kind="static", duration_s=samples / FS_HZ,
                       settle_s=0.5, samples=samples, **extra)  # type: ignore[arg-type]


def rate_step(rate_dps: float, samples: int = 16384, **extra: object) -> PlannedStep:
    return PlannedStep(id=str(extra.pop("id", "rate")), kind="constant_rate", axis="inner",
                       duration_s=samples / FS_HZ, settle_s=1.0, samples=samples,
                       rate_dps=rate_dps, **extra)  # type: ignore[arg-type]


def fundamental(x: np.ndarray, cycles: int) -> complex:
    """One-sided complex amplitude of the DFT bin ``cycles`` (mean removed)."""
    spectrum = np.fft.rfft(np.asarray(x) - np.mean(x))
    return complex(2.0 * spectrum[cycles] / len(x))


def aligned_daq(sim: SimulatedStep, channel: str) -> np.ndarray:
    """DAQ samples from the trigger on, as many as the table log (exact when drift is 0)."""
    start = int(np.argmax(np.asarray(sim.daq["trigger"]) > 0.5))
    return np.asarray(sim.daq[channel][start: start + len(sim.table)])


def model_from_yaml(tmp_path: Path, base: RigModel, *, sensor: dict | None = None,
                    table_axis: dict | None = None, table: dict | None = None,
                    daq: dict | None = None) -> RigModel:
    """Switch effects on *in a model YAML file* and load it back through load_rig_model."""
    doc = model_document(base)
    doc["sensors"][0].update(sensor or {})
    for axis in ("inner", "outer"):
        doc["table"][axis].update(table_axis or {})
    doc["table"].update(table or {})
    doc["daq"].update(daq or {})
    path = tmp_path / "model.yaml"
    yaml = YAML(typ="safe", pure=True)
    yaml.representer.ignore_aliases = lambda *_args: True  # aatest refuses YAML aliases
    with path.open("w", encoding="utf-8") as fh:
        yaml.dump(doc, fh)
    return load_rig_model(path)
