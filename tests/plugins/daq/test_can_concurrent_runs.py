"""Two `aatest run`s at once on one host, each against its own `aatest sim-server modbus`, with
the CAN loggers on two udp_multicast groups of the one python-can port (slow: real processes,
paced UDP). Before the groups were isolated each run heard the other's logger and faulted."""

from __future__ import annotations

import json
import os
import select
import signal
import socket
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.slow
PROCEDURE = """\
procedure: concurrent-can
sensor: {model: sr207, serial: "A1234"}
rig: {turntable: sim, daq: sim, chamber: none}
sampling: {rate_hz: 2000, samples: 8000, settle_s: 1}
steps:
  - sine: {axis: inner, frequency_hz: 1.0, accel_dps2: 400, snap: coherent}
analysis: [sync, reference, scale_factor]
report: {template: calibration-certificate, sign: false}
"""
#: the twin's reference sensor (test_sim_server_cli pins the same value over the same path)
TRUE_SCALE_V_PER_DPS2 = 0.004014


def _free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def _start_server(port: int, seed: int, group: str) -> subprocess.Popen[str]:
    server = subprocess.Popen(
        [sys.executable, "-m", "aatest.cli", "sim-server", "modbus", "--host", "127.0.0.1",
         "--port", str(port), "--seed", str(seed), "--can-interface", "udp_multicast",
         "--can-channel", group], stdout=subprocess.PIPE, text=True)
    assert server.stdout is not None
    ready, _, _ = select.select([server.stdout], [], [], 30.0)
    if not ready:
        pytest.fail("sim-server printed nothing")
    assert group in server.stdout.readline()
    return server


def _start_run(work: Path, port: int, group: str) -> subprocess.Popen[str]:
    work.mkdir()
    (work / "p.yaml").write_text(PROCEDURE)
    (work / "rig.yaml").write_text(
        f"turntable: {{plugin: modbus, host: 127.0.0.1, port: {port}}}\n"
        f"daq: {{plugin: can, interface: udp_multicast, channel: '{group}'}}\n")
    env = {**os.environ, "AATEST_RECORDS": f"sqlite:///{work / 'records.db'}"}
    return subprocess.Popen(
        [sys.executable, "-m", "aatest.cli", "run", str(work / "p.yaml"), "--rig",
         str(work / "rig.yaml"), "--out", str(work / "r"), "--no-progress"],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env)


def _stop(proc: subprocess.Popen[str]) -> None:
    if proc.poll() is None:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(10.0)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(5.0)


def test_two_concurrent_runs_each_finish_with_their_own_data(tmp_path: Path) -> None:
    pytest.importorskip("msgpack", reason="python-can's udp_multicast needs msgpack")
    if sys.platform != "linux":
        pytest.skip("IP_MULTICAST_ALL is a Linux option")
    octet = 10 + os.getpid() % 200
    rigs = [(_free_port(), seed, f"239.75.{octet}.{20 + seed}") for seed in (5, 6)]
    servers: list[subprocess.Popen[str]] = []
    runs: list[subprocess.Popen[str]] = []
    try:
        servers = [_start_server(port, seed, group) for port, seed, group in rigs]
        runs = [_start_run(tmp_path / f"run{seed}", port, group) for port, seed, group in rigs]
        outputs = [run.communicate(timeout=180.0)[0] for run in runs]
    finally:
        for proc in (*runs, *servers):
            _stop(proc)
    for run, output in zip(runs, outputs, strict=True):
        assert run.returncode == 0, output
    for _port, seed, _group in rigs:
        results = json.loads((tmp_path / f"run{seed}" / "r" / "results.json").read_text())
        scale = results["analysis"]["scale_factor"]["v_sz"]["scale_v_per_dps2"]
        # one 8000-sample sine step recovers the twin's scale factor to well inside 1 %
        assert scale == pytest.approx(TRUE_SCALE_V_PER_DPS2, rel=0.01)
