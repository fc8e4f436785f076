"""Misalignment: the published formulas, the CSV command and the matrix estimator."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from analyse import analyse
from synthetic_rig import sine_step

from aatest.engine.errors import ImportDataError
from aatest.engine.steps import Mounting
from aatest.plugins.analysis.misalignment import misalignment_from_spectra
from aatest.twin.api import simulate_dataset


def _write(tmp_path: Path, rows: list[str]) -> Path:
    path = tmp_path / "spectra.csv"
    path.write_text("set,experiment,sensor,re,im\n" + "\n".join(rows) + "\n")
    return path


def _unit_rows(set_name: str, pivoted: bool, cross: dict[str, tuple[float, float]]) -> list[str]:
    """Responses of SZ/SY/SX with given (x, y) cross responses, main response 0.4 V."""
    axes = {"SZ": ("I", "P", "O"), "SY": ("O", "I", "P"), "SX": ("P", "O", "I")}
    exp_of = {"I": 1, "O": 2, "P": 3}
    rows = []
    for sensor, (z, x, y) in axes.items():
        values = {z: 0.4, x: 0.4 * cross[sensor][0], y: 0.4 * cross[sensor][1]}
        for axis, v in values.items():
            e = exp_of[axis] + (3 if pivoted else 0)
            rows.append(f"{set_name},{e},{sensor},{v},0.0")
    return rows


def test_published_formulas(tmp_path: Path) -> None:
    orig = {"SZ": (0.006, 0.008), "SY": (0.001, 0.0), "SX": (0.0, -0.002)}
    piv = {"SZ": (0.002, 0.0), "SY": (0.001, 0.0), "SX": (0.0, 0.002)}
    path = _write(tmp_path, _unit_rows("A", False, orig) + _unit_rows("B", True, piv))
    out = misalignment_from_spectra(path)
    sz = out["sets"]["A"]["SZ"]
    assert sz["cross_ratio_x"] == pytest.approx(0.006)
    assert sz["cross_ratio_y"] == pytest.approx(0.008)
    assert sz["delta_A"] == pytest.approx([0.4 * 0.01, 0.0])
    assert sz["delta_e_deg"] == pytest.approx(np.degrees(np.arcsin(0.01)))
    delta = out["scenarios"]["1"]["SZ"]["delta_deg"]
    assert delta == pytest.approx((np.degrees(np.arcsin(0.01)) - np.degrees(np.arcsin(0.002))) / 2)
    assert out["scenarios"]["1"]["SY"]["delta_deg"] == pytest.approx(0.0)


def test_anti_phase_cross_responses_use_the_complex_root(tmp_path: Path) -> None:
    rows = _unit_rows("A", False, {"SZ": (0.003, 0.0), "SY": (0.0, 0.0), "SX": (0.0, 0.0)})
    rows = [r.replace("A,2,SZ,0.0,0.0", "A,2,SZ,0.0,0.0016") for r in rows]
    sz = misalignment_from_spectra(_write(tmp_path, rows))["sets"]["A"]["SZ"]
    expected = np.sqrt(complex((0.4 * 0.003) ** 2 + (0.0016j) ** 2))
    assert complex(*sz["delta_A"]) == pytest.approx(expected)


@pytest.mark.parametrize("row, match", [
    ("A,4,SZ,1,0", "does not belong to the original"), ("Q,1,SZ,1,0", "not one of A..H"),
    ("A,1,SQ,1,0", "SZ, SY, SX"), ("A,1,SZ,abc,0", "not numeric")],
    ids=["exp-set", "set", "sensor", "number"])
def test_csv_errors_name_file_and_line(tmp_path: Path, row: str, match: str) -> None:
    path = _write(tmp_path, ["A,1,SZ,0.4,0", row])
    with pytest.raises(ImportDataError, match=f"spectra.csv:3: .*{match}"):
        misalignment_from_spectra(path)


def test_missing_column(tmp_path: Path) -> None:
    path = tmp_path / "s.csv"
    path.write_text("set,experiment,sensor,re\nA,1,SZ,1\n")
    with pytest.raises(ImportDataError, match=r"s\.csv:1: missing column"):
        misalignment_from_spectra(path)


def _misalignment_steps(n: int = 8192, reps: int = 2) -> list:
    steps = []
    for set_name, pivoted in (("A", False), ("B", True)):
        for rep in range(1, reps + 1):
            for e, (axis, inner) in enumerate([("inner", 0.0), ("outer", 0.0), ("outer", 90.0)]):
                exp = e + 1 + (3 if pivoted else 0)
                steps.append(sine_step(f"{set_name}{rep}e{exp}", 8, 100.0, samples=n, axis=axis,
                                       inner_deg=inner, repetition=rep, settle_s=1.0,
                                       mounting=Mounting(pivoted=pivoted, scenario=set_name,
                                                         experiment=exp)))
    return steps


def test_matrix_estimator_against_twin(realistic_unit) -> None:  # type: ignore[no-untyped-def]
    # the play (hysteresis, 0.2 °/s²) and threshold terms shrink the ≈0.5 °/s² cross responses
    # by ≈20 % — a real sensor non-linearity, but not misalignment: switched off here
    sensors = [s.model_copy(update={"hysteresis": None, "resolution_dps2": 0.0})
               for s in realistic_unit.sensors]
    model = realistic_unit.model_copy(update={"sensors": sensors})
    # one World for the whole sequence: the unit's (random) first mounting is shared by all
    data = simulate_dataset(model, _misalignment_steps(), seed=5)
    out = analyse("misalignment", data)
    assert set(out["sets"]) == {"A", "B"} and "1" in out["scenarios"]
    for s in model.sensors:
        mis, cross = s.misalignment, s.cross_axis
        az = np.radians(mis.azimuth_deg)
        truth = np.degrees([np.tan(np.radians(mis.angle_deg)) * np.cos(az) + cross.ratio_x,
                            np.tan(np.radians(mis.angle_deg)) * np.sin(az) + cross.ratio_y])
        est = out["matrix"]["scenarios"]["1"][s.channel]
        assert est["sensor_tilt_x_deg"] == pytest.approx(truth[0], abs=0.02)
        assert est["sensor_tilt_y_deg"] == pytest.approx(truth[1], abs=0.02)
