"""The documented rig's defaults, named once (docs/method.md §1.2).

The rate both loggers record at, the table's axis limits and its log buffer are stated here and
nowhere else: the twin simulates them, the engine's envelope and step records default to them,
the procedure's sampling, the results and the uncertainty budget assume them when a run does
not say otherwise, and the plugins' options start from them. A leaf module (it imports
nothing), so every layer — :mod:`aatest.results` included — can read it.
"""

from __future__ import annotations

#: the rate the table controller and the sensor logger record at, Hz (2 kHz)
LOG_RATE_HZ = 2000.0
#: inner-axis rate (°/s) and acceleration (°/s²) limits
INNER_RATE_DPS, INNER_ACCEL_DPS2 = 1200.0, 1000.0
#: outer-axis rate (°/s) and acceleration (°/s²) limits
OUTER_RATE_DPS, OUTER_ACCEL_DPS2 = 500.0, 200.0
#: samples the table controller's log buffer holds
LOG_CAPACITY_SAMPLES = 230_000
#: samples per record when the procedure states none (2^17, ≈65.5 s at 2 kHz)
RECORD_SAMPLES = 131_072
