"""Recordings from the digital twin with their truth (known model, known clock)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

from aatest.engine.steps import PlannedStep
from aatest.recording.dataset import Dataset, StepData


def twin_dataset(model: Any, steps: Sequence[PlannedStep], seed: int = 11,
                 temperatures_c: Sequence[float | None] | None = None
                 ) -> tuple[Dataset, list[dict[str, Any]]]:
    """Simulate each step on the twin; return the Dataset and each step's truth dict."""
    from aatest.twin.api import sensor_infos, simulate_step

    temps = list(temperatures_c) if temperatures_c is not None else [None] * len(steps)
    data, truths = [], []
    for i, (step, temp) in enumerate(zip(steps, temps, strict=True)):
        sim = simulate_step(model, step, seed + i, temperature_c=temp)
        data.append(StepData(step=step, table=sim.table, daq=sim.daq))
        truths.append(sim.truth)
    return Dataset(procedure="twin", sample_rate_hz=2000.0, sensors=sensor_infos(model),
                   steps=tuple(data), source=Path("<twin>")), truths
