"""Every scale-factor reference option runs through ``aatest run`` and the result names it."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

PROCEDURE = """procedure: quick-scale-factor-{name}
sensor: {{model: sr207, serial: "T0001"}}
sampling: {{rate_hz: 2000, samples: 8192, settle_s: 0.5}}
steps:
  - sine: {{axis: inner, frequency_hz: 1.0, accel_dps2: 400}}
analysis:
  - scale_factor: {{reference: {name}}}
report: {{template: calibration-certificate, sign: false}}
"""


@pytest.mark.parametrize("name, recorded", [
    ("fit", "fit"), ("table_estimate", "table_estimate"), ("central", "central"),
    ("five_point", "five_point"), ("smoothed", "smoothed"), ("sliding_mode", "sliding_mode"),
    ("smooth", "smoothed"),
], ids=["fit", "table_estimate", "central", "five_point", "smoothed", "sliding_mode",
        "old-name-smooth"])
def test_reference_option_end_to_end(name: str, recorded: str, tmp_path: Path) -> None:
    procedure = tmp_path / "p.yaml"
    procedure.write_text(PROCEDURE.format(name=name), encoding="utf-8")
    run_dir = tmp_path / "run"
    done = subprocess.run(
        [sys.executable, "-m", "aatest.cli", "run", str(procedure), "--out", str(run_dir),
         "--no-progress", "--seed", "2"],
        capture_output=True, text=True, timeout=300, stdin=subprocess.DEVNULL, check=False)
    assert done.returncode == 0, done.stderr
    results = json.loads((run_dir / "results.json").read_text(encoding="utf-8"))
    # sync was pulled in by scale_factor's requirement although the procedure does not list it
    assert set(results["analysis"]) == {"sync", "scale_factor"}
    sf = results["analysis"]["scale_factor"]["v_sz"]
    assert sf["reference"] == recorded
    # every reference recovers the twin's sensor (datasheet ± its 0.06 % error) to 0.5 %
    assert abs(sf["scale_deviation_pct"]) < 0.5
    assert results["metadata"]["analysis"] == [{"scale_factor": {"reference": name}}]
