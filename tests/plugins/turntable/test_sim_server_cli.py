"""`aatest sim-server modbus` in its own process; `aatest run --rig` reaches the table over
Modbus TCP and the CAN logger over udp_multicast on loopback (slow: real processes, paced UDP)."""

from __future__ import annotations

import json
import os
import time
from collections.abc import Callable
from pathlib import Path

import pytest
from typer.testing import CliRunner

from aatest.cli import app
from aatest.testing.sim_process import SimServerProcess, multicast_group

pytestmark = pytest.mark.slow


@pytest.mark.usefixtures("rig_entry_points")
def test_run_against_a_separate_sim_server(tmp_path: Path, cross_process_run: Callable[
        [Path, int, str], tuple[Path, Path]]) -> None:
    pytest.importorskip("msgpack", reason="python-can's udp_multicast needs msgpack")
    group = multicast_group(74)
    env = {**os.environ, "AATEST_SIM_CAN_CHANNEL": group,
           "AATEST_SIM_CAN_INTERFACE": "udp_multicast"}
    server = SimServerProcess("modbus", args=("--seed", "5"), env=env)
    port = server.port
    try:
        banner = server.start().banner
        assert f"Modbus TCP 127.0.0.1:{port}" in banner and group in banner
        procedure, rig = cross_process_run(tmp_path, port, group)
        started = time.monotonic()
        result = CliRunner().invoke(app, ["run", str(procedure), "--rig", str(rig),
                                          "--out", str(tmp_path / "r")])
        assert result.exit_code == 0, result.output
        assert time.monotonic() - started < 60.0
        results = json.loads((tmp_path / "r" / "results.json").read_text())
        sf = results["analysis"]["scale_factor"]
        assert sf["v_sz"]["scale_v_per_dps2"] == pytest.approx(0.004014, rel=0.01)
        # the drivers read the server's identification: a simulation, marked as such
        assert results["metadata"]["simulated_parts"] == ["daq:can", "turntable:modbus"]
        assert results["certificate_number"].startswith("SIM-")
        assert "Simulation report — not a calibration certificate" in result.output
        assert 'id="simulation-mark"' in (tmp_path / "r" / "report.html").read_text()
    finally:
        server.stop()
