"""The example vendor package installed for real (pip, fresh venv) and used through the CLI.

Slow-ish (≈10 s for the install, once per module): it is the proof that a vendor needs nothing
but aatest's public plugin API and its own ``pyproject.toml``.
"""

from __future__ import annotations

import json
import math
import os
import re
import subprocess
from pathlib import Path

import pytest

from aatest.engine import registry
from aatest.engine.errors import EXIT_BAD_INPUT, EXIT_OK, PluginError
from aatest.twin.model import DaqModel

PROCEDURE = """\
procedure: vendor-sine
sensor: {{model: acme-mems-aa, serial: "M-7"}}
rig: {{turntable: acme-single-axis, daq: sim, chamber: none}}
sampling: {{rate_hz: 2000, samples: 8000, settle_s: 1}}
steps:
  - sine: {{axis: {axis}, frequency_hz: 2.0, accel_dps2: {accel}, snap: coherent}}
analysis: [sync]
report: {{template: calibration-certificate, sign: false}}
"""


def _procedure(tmp_path: Path, axis: str, accel_dps2: float) -> Path:
    path = tmp_path / f"vendor-{axis}-{accel_dps2:g}.yaml"
    path.write_text(PROCEDURE.format(axis=axis, accel=accel_dps2))
    return path


def _aatest(scripts: Path, *args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    """The ``aatest`` command of the fresh venv (no PYTHONPATH leaking in from this process)."""
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    return subprocess.run([scripts / "aatest", *args], cwd=cwd, env=env, check=False,
                          capture_output=True, text=True, timeout=300)


def test_installed_only_in_the_fresh_venv(vendor_venv: Path) -> None:
    where = subprocess.run(
        [vendor_venv / "python", "-c", "import aatest_vendor_example as m; print(m.__file__)"],
        capture_output=True, text=True, check=True).stdout.strip()
    assert Path(where).is_relative_to(vendor_venv.parent), where  # not the source tree
    with pytest.raises(PluginError, match="no turntable plugin named 'acme-single-axis'"):
        registry.load("turntable", "acme-single-axis")  # this process never saw it


def test_listed_by_aatest_plugins(vendor_venv: Path, tmp_path: Path) -> None:
    result = _aatest(vendor_venv, "plugins", cwd=tmp_path)
    assert result.returncode == EXIT_OK, result.stdout + result.stderr
    lines = [line.split() for line in result.stdout.splitlines()]
    assert ["acme-single-axis", "aatest-vendor-example", "0.1.0"] in lines
    assert ["acme-mems-aa", "aatest-vendor-example", "0.1.0"] in lines
    assert ["sim", "aatest", "0.1.0"] in lines


@pytest.mark.parametrize(("axis", "accel_dps2", "reason"), [
    ("outer", 100.0, r"the step moves the outer axis, an axis this table does not have "
                     r"\(declared axes: inner\) \[outer\.present\]"),
    ("inner", 1550.0, r"1550 °/s² exceeds inner\.accel_dps2 1500 °/s² .*\[inner\.accel_dps2\]"),
], ids=["outer-axis", "beyond-vendor-envelope"])
def test_planner_refuses(vendor_venv: Path, tmp_path: Path, axis: str, accel_dps2: float,
                         reason: str) -> None:
    procedure = _procedure(tmp_path, axis, accel_dps2)
    result = _aatest(vendor_venv, "validate", str(procedure), cwd=tmp_path)
    assert result.returncode == EXIT_BAD_INPUT, result.stdout + result.stderr
    located = re.escape(f"{procedure}:6:5: ") + ".*" + reason  # FILE:LINE:COLUMN: reason
    assert any(re.search(located, line) for line in result.stderr.splitlines()), result.stderr


def test_run_on_the_twin(vendor_venv: Path, tmp_path: Path) -> None:
    # 1200 °/s² exceeds the built-in two-axis table (1000 °/s²) but not the SR-1 (1500 °/s²)
    out = tmp_path / "run"
    result = _aatest(vendor_venv, "run", str(_procedure(tmp_path, "inner", 1200.0)),
                     "--out", str(out), cwd=tmp_path)
    assert result.returncode == EXIT_OK, result.stdout + result.stderr
    results = json.loads((out / "results.json").read_text())
    assert results["rig"]["turntable"]["plugin"] == "acme-single-axis"
    meta = results["metadata"]
    assert meta["plugin_versions"]["turntable:acme-single-axis"] == "aatest-vendor-example 0.1.0"
    assert meta["plugin_versions"]["sensor:acme-mems-aa"] == "aatest-vendor-example 0.1.0"
    assert meta["table_serial"] == "SR1-0042"
    [step] = results["steps"]
    assert (step["status"], step["axis"], step["accel_dps2"]) == ("recorded", "inner", 1200.0)
    # a sine of peak acceleration A at f has amplitude A / (2πf)²
    # A = α/(2πf)²: a handful of roundings of exact inputs, ≲ 1e-15 relative on any CPU
    assert math.isclose(step["amplitude_deg"], 1200.0 / (2 * math.pi * 2.0) ** 2, rel_tol=1e-12)
    assert step["table_samples"] == 8000 < step["daq_samples"]  # the DAQ logs before and after
    sync, daq = results["analysis"]["sync"], DaqModel()
    # every sync edge of the 4 s step latched by the table, the DAQ started start_lead_s earlier
    assert abs(sync["edges_used"] - 4.0 * daq.sync_pulse_hz) <= 2
    assert abs(sync["offset_s"] + daq.start_lead_s) < 1e-3
    assert sync["residual_rms_us"] < 0.1 * 1e6 / 2000.0
    assert (out / "report.html").stat().st_size > 0
