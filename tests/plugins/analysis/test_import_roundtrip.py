"""Analyses on an exported-then-imported directory give the numbers of the recording."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
from synthetic_rig import sine_step
from twin_helpers import twin_dataset

from aatest.engine.analysis.passes import run_analyses


def _analyse(data):  # type: ignore[no-untyped-def]
    done = run_analyses(data, ["sync", "scale_factor", "frf"])
    return {key: result.model_dump() for key, result in done.values.items()}


@pytest.mark.pinned
def test_same_numbers_after_csv_roundtrip(realistic_unit: Any, tmp_path: Path) -> None:
    from aatest.recording.data.exporter import export_csv
    from aatest.recording.data.importer import import_dataset

    model = realistic_unit.model_copy(update={"sensors": realistic_unit.sensors[:1]})
    steps = [sine_step("cal", 8, 400.0, samples=8192, settle_s=1.0),
             sine_step("f5", 41, 100.0, samples=8192, settle_s=1.0)]
    data, _ = twin_dataset(model, steps)
    export_csv(data, tmp_path / "export")
    imported = import_dataset(tmp_path / "export")
    a, b = _analyse(data), _analyse(imported)
    assert b["sync"]["drift_ppm"] == pytest.approx(a["sync"]["drift_ppm"], abs=1e-6)
    assert b["sync"]["offset_s"] == pytest.approx(a["sync"]["offset_s"], abs=1e-9)
    assert b["scale_factor"]["v_sz"]["scale_v_per_dps2"] == pytest.approx(
        a["scale_factor"]["v_sz"]["scale_v_per_dps2"], rel=1e-9)
    for pa, pb in zip(a["frf"]["v_sz"], b["frf"]["v_sz"], strict=True):
        assert pb["gain_db"] == pytest.approx(pa["gain_db"], abs=1e-9)
        assert pb["phase_deg"] == pytest.approx(pa["phase_deg"], abs=1e-7)
