"""The lab profile: who issues the certificates, with which prefix, and how often units return.

Read from ``--lab lab.yaml`` or ``AATEST_LAB``; without one, a neutral default is used so a
single PC can work out of the box::

    name: Example Calibration Lab
    certificate_prefix: LAB            # numbers look like LAB-2026-000123
    calibration_interval_months: 12    # next due date = last calibration + interval
    frf_reference_frequency_hz: 1.0    # the FRF point tracked in the history
"""

from __future__ import annotations

import os
from pathlib import Path

from pydantic import BaseModel, ConfigDict, Field

LAB_ENV = "AATEST_LAB"


class LabProfile(BaseModel):
    """A calibration lab as the records store needs to know it."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    name: str = Field("aatest lab", min_length=1, description="lab name on the records")
    certificate_prefix: str = Field(
        "LAB", pattern=r"^[A-Z0-9][A-Z0-9_]{0,15}$", description="prefix of certificate numbers")
    calibration_interval_months: int = Field(12, ge=1, le=120, description="recall interval")
    frf_reference_frequency_hz: float = Field(
        1.0, gt=0, description="frequency whose FRF gain is tracked over time, Hz")


def load_lab(path: Path | None = None) -> LabProfile:
    """The lab profile from ``path``, else ``AATEST_LAB``, else the defaults.

    YAML errors are reported as ``FILE:LINE:COLUMN: field: message`` (exit 2) by the engine's
    model loader.
    """
    from aatest.engine.procedure.yaml_loader import load_model_file

    chosen = path or (Path(os.environ[LAB_ENV]) if os.environ.get(LAB_ENV) else None)
    if chosen is None:
        return LabProfile()
    return load_model_file(chosen, LabProfile)
