"""Contract rules of diagnose that must hold whatever the fit finds (docs/interfaces.md §4)."""

from __future__ import annotations

import pytest

from aatest.diagnose.pipeline import diagnose_dataset
from aatest.diagnose.scenarios import Hidden, scenario_dataset, without_latch

SAMPLES = 2**13


def _effects(doc: dict) -> list[str]:
    return [f["effect"] for f in doc["findings"]]


def _row(doc: dict, effect: str) -> dict:
    return next(c for c in doc["candidates"] if c["effect"] == effect)


def test_a_sub_sample_delay_is_evidence_only_with_latch_times() -> None:
    """0.3 ms < one 0.5 ms sample: without ``fp_latch_s`` the sync cannot resolve it."""
    data = scenario_dataset([Hidden("time_delay", {"delay_s": 3e-4}, ())], 31, SAMPLES)
    doc = diagnose_dataset(without_latch(data))
    assert not doc["logger"]["fp_latch_s"]
    assert "time_delay" not in _effects(doc)
    assert "jerk_sensitivity" not in _effects(doc)
    latched = diagnose_dataset(data)
    assert _effects(latched) == ["time_delay"]
    assert latched["findings"][0]["parameters"]["delay_s"] == pytest.approx(3e-4, rel=0.25)


def test_clock_drift_within_tolerance_is_not_a_finding() -> None:
    doc = diagnose_dataset(scenario_dataset([Hidden("clock_drift", {"drift_ppm": 12.0}, ())], 32,
                                            SAMPLES))
    assert _effects(doc) == []
    row = _row(doc, "clock_drift")
    assert row["parameters"]["drift_ppm"] == pytest.approx(12.0, abs=0.5)
    assert "tolerance" in row["reason"]


def test_clock_drift_beyond_tolerance_is_found_from_the_edges() -> None:
    doc = diagnose_dataset(scenario_dataset([Hidden("clock_drift", {"drift_ppm": -80.0}, ())], 33,
                                            SAMPLES))
    assert _effects(doc) == ["clock_drift"]
    finding = doc["findings"][0]
    assert finding["parameters"]["drift_ppm"] == pytest.approx(-80.0, abs=1.0)
    lo, hi = finding["ci95"]["drift_ppm"]
    assert lo <= finding["parameters"]["drift_ppm"] <= hi
    assert finding["attributed_to"] == "logger"
    assert finding["evidence"]["rmse_v_after"] < finding["evidence"]["rmse_v_before"]


def test_a_lag_is_never_called_jerk_and_a_lead_never_delay() -> None:
    lead = Hidden("jerk_sensitivity", {"coefficient_v_per_dps3": 0.004014 * 3e-3}, ())
    doc = diagnose_dataset(scenario_dataset([lead], 34, SAMPLES))
    assert _effects(doc) == ["jerk_sensitivity"]
    assert doc["findings"][0]["parameters"]["coefficient_v_per_dps3"] > 0
    assert "time_delay" not in _effects(doc)


def test_table_effects_are_attributed_to_the_table() -> None:
    vib = Hidden("motor_vibration", {"frequency_hz": 35.0, "amplitude_dps2": 5.0}, ())
    doc = diagnose_dataset(scenario_dataset([vib], 35, SAMPLES))
    assert _effects(doc) == ["motor_vibration"]
    assert doc["findings"][0]["attributed_to"] == "table"
    assert doc["findings"][0]["parameters"]["frequency_hz"] == pytest.approx(35.0, abs=0.05)


def test_json_shape_matches_the_contract() -> None:
    hidden = Hidden("g_sensitivity", {"coefficient_dps2_per_g": 1.5}, ())
    doc = diagnose_dataset(scenario_dataset([hidden], 36, SAMPLES))
    assert set(doc) >= {"baseline", "findings", "gain", "candidates"}
    assert set(doc["gain"]) >= {"rmse_v_before", "rmse_v_after", "reduction_pct"}
    for c in doc["candidates"]:
        assert {"effect", "delta_bic", "accepted"} <= set(c)
    f = doc["findings"][0]
    assert set(f["evidence"]) == {"delta_bic", "rmse_v_before", "rmse_v_after"}
    assert set(f["parameters"]) == set(f["ci95"]) == {"coefficient_dps2_per_g"}
    assert f["parameters"]["coefficient_dps2_per_g"] == pytest.approx(1.5, rel=0.1)


def _without_table_pulse(directory) -> None:
    """Another tool without the freeze-pulse wiring: the table's sync column stays 0."""
    for path in directory.glob("*_table.csv"):
        lines = path.read_text().splitlines()
        col = lines[0].split(",").index("sync_pulse")
        rows = [",".join("0" if k == col else v for k, v in enumerate(line.split(",")))
                for line in lines[1:]]
        path.write_text("\n".join([lines[0], *rows]) + "\n")


@pytest.mark.parametrize("drift_ppm", [120.0])
def test_without_sync_edges_drift_comes_from_the_phase_trend(tmp_path, drift_ppm: float) -> None:
    from aatest.recording import read_dataset
    from aatest.recording.data.exporter import export_csv

    hidden = [Hidden("clock_drift", {"drift_ppm": drift_ppm}, ())] if drift_ppm else []
    export_csv(scenario_dataset(hidden, 37, SAMPLES), tmp_path)
    _without_table_pulse(tmp_path)
    doc = diagnose_dataset(read_dataset(tmp_path))
    assert doc["steps_skipped"] == []
    if not drift_ppm:
        assert _effects(doc) == []
        return
    assert _effects(doc) == ["clock_drift"]
    finding = doc["findings"][0]
    assert finding["source"].startswith("phase trend")
    assert finding["parameters"]["drift_ppm"] == pytest.approx(drift_ppm, rel=0.05)
