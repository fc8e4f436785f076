"""`aatest sim-server modbus` in its own process; `aatest run --rig` reaches the table over
Modbus TCP and the CAN logger over udp_multicast on loopback (slow: real processes, paced UDP)."""

from __future__ import annotations

import json
import os
import select
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from aatest.cli import app

pytestmark = pytest.mark.slow
PROCEDURE = """\
procedure: cross-process
sensor: {model: sr207, serial: "A1234"}
rig: {turntable: sim, daq: sim, chamber: none}
sampling: {rate_hz: 2000, samples: 8000, settle_s: 1}
steps:
  - sine: {axis: inner, frequency_hz: 1.0, accel_dps2: 400, snap: coherent}
analysis: [sync, reference, scale_factor]
report: {template: calibration-certificate, sign: false}
"""


def _free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def _wait_for_banner(proc: subprocess.Popen[str], timeout_s: float) -> str:
    assert proc.stdout is not None
    ready, _, _ = select.select([proc.stdout], [], [], timeout_s)
    if not ready:
        pytest.fail("sim-server printed nothing")
    return proc.stdout.readline()


@pytest.mark.usefixtures("rig_entry_points")
def test_run_against_a_separate_sim_server(tmp_path: Path) -> None:
    pytest.importorskip("msgpack", reason="python-can's udp_multicast needs msgpack")
    port = _free_port()
    group = f"239.74.163.{np.random.default_rng(port).integers(10, 250)}"
    env = {**os.environ, "AATEST_SIM_CAN_CHANNEL": group,
           "AATEST_SIM_CAN_INTERFACE": "udp_multicast"}
    server = subprocess.Popen(
        [sys.executable, "-m", "aatest.cli", "sim-server", "modbus", "--host", "127.0.0.1",
         "--port", str(port), "--seed", "5"], stdout=subprocess.PIPE, text=True, env=env)
    try:
        banner = _wait_for_banner(server, 30.0)
        assert f"Modbus TCP 127.0.0.1:{port}" in banner and group in banner
        (tmp_path / "p.yaml").write_text(PROCEDURE)
        (tmp_path / "rig.yaml").write_text(
            f"turntable: {{plugin: modbus, host: 127.0.0.1, port: {port}}}\n"
            f"daq: {{plugin: can, interface: udp_multicast, channel: '{group}'}}\n")
        started = time.monotonic()
        result = CliRunner().invoke(app, ["run", str(tmp_path / "p.yaml"), "--rig",
                                          str(tmp_path / "rig.yaml"), "--out", str(tmp_path / "r")])
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
        server.send_signal(signal.SIGINT)
        try:
            server.wait(10.0)
        except subprocess.TimeoutExpired:
            server.kill()
            server.wait(5.0)
