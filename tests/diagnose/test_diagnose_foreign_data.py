"""``aatest diagnose`` on data another tool wrote (no twin involved), as a user runs it."""

import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from aatest.cli import app

from foreign_dataset import Hidden, write_dataset

CASES = {
    "clean": (Hidden(), False),
    "clean-latched": (Hidden(), True),
    "bias-temperature": (Hidden("bias_temperature", 0.0004), False),
    "delay-3ms-latched": (Hidden("time_delay", 0.003), True),
    "cubic": (Hidden("nonlinearity_cubic", 0.02), False),
    "drift-50ppm-latched": (Hidden("clock_drift", 50.0), True),
    "drift-50ppm": (Hidden("clock_drift", 50.0), False),
}
#: 50 ppm over an 8 s record is < 1 sample: the sync edges cannot show it; the phase trend can
#: (diagnose refines unlatched edge drift with the phase trend, so no known gap remains)
KNOWN_GAPS: dict[str, str] = {}
PARAMETER = {"bias_temperature": "coefficient_v_per_c", "time_delay": "delay_s",
             "nonlinearity_cubic": "c3", "clock_drift": "drift_ppm"}


def _diagnose(data: Path) -> tuple[int, dict]:
    out = data.parent / "diagnosis.json"
    result = CliRunner().invoke(app, ["diagnose", str(data), "--json", str(out)])
    assert "Traceback" not in result.output
    return result.exit_code, json.loads(out.read_text())


@pytest.mark.parametrize(
    "case",
    [pytest.param(c, marks=pytest.mark.xfail(reason=KNOWN_GAPS[c], strict=True)) if c in KNOWN_GAPS
     else c for c in CASES],
    ids=list(CASES),
)
def test_foreign_dataset(tmp_path: Path, case: str) -> None:
    hidden, latch = CASES[case]
    code, doc = _diagnose(write_dataset(tmp_path / "data", hidden, latch=latch, seed=7))
    found = {f["effect"]: f["parameters"] for f in doc["findings"]}
    if hidden.effect is None:
        assert (code, found) == (0, {}), "clean data must yield no finding"
        return
    assert code == 1 and list(found) == [hidden.effect], found
    value = found[hidden.effect][PARAMETER[hidden.effect]]
    assert value == pytest.approx(hidden.value, rel=0.25)
    assert doc["gain"]["rmse_v_after"] < doc["gain"]["rmse_v_before"]
