"""Step builders for the twin tests (imported by name: tests have no packages)."""

from __future__ import annotations

from aatest.engine.steps import PlannedStep

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
