"""A long static record through the real protocols (issue 31 item 7): the `modbus` table and
the `can` logger on udp_multicast against an ``aatest sim-server modbus`` in another process.

Two static steps, axis up and down (three minutes of lab time at 1 kHz, 180 000 sample frames),
each longer than the table's declared log buffer (20 000 samples), so `validate` accepts them
only because the CAN logger streams: the table arms its head before the logger's trigger, the
logger ends its timed record itself and streams it in chunks, and `[sync, bias, noise, drift]`
reduce it. Checked: the run completes (exit 0), sync is fitted on the head and says how much
of the record it covers, bias and noise agree with the same procedure on the in-process twin
within their U (and bias with the twin's truth), and the plugin never held more than a chunk
and a logger block.
"""

from __future__ import annotations

import json
import os
import sys
import textwrap
from pathlib import Path
from typing import Any

import pytest
from typer.testing import CliRunner

from aatest.cli import app
from aatest.engine.datasheet import SensorDatasheet
from aatest.engine.run import session
from aatest.plugins.daq.can import CanDaq
from aatest.testing.sim_process import SimServerProcess, multicast_group
from aatest.twin.defaults import realistic_rig_model
from aatest.twin.servers.can_sim import CHUNK_MARK_FRAMES, FRAME_RATE_ENV
from aatest.twin.truth import bias_truth_v

pytestmark = pytest.mark.slow

RECORD_S, FS_HZ, HEAD_SAMPLES = 90.0, 1000.0, 20_000
#: the simulated logger's pace (frames/s): half its default, so a host starved of CPU by a
#: loaded machine still keeps up with the UDP stream (a loss would be a RigFault, not silent)
PACE_HZ = 5000
PROCEDURE = textwrap.dedent(f"""\
    procedure: can-long-static
    sensor: {{model: sr207, serial: "C-1"}}
    rig: {{turntable: sim, daq: sim, chamber: none}}
    sampling: {{rate_hz: {FS_HZ:g}, settle_s: 2}}
    steps:
      - static: {{label: up, inner_deg: 0, outer_deg: 0, duration_s: {RECORD_S:g},
                  motor_on: false}}
      - static: {{label: down, inner_deg: 0, outer_deg: 180, duration_s: {RECORD_S:g},
                  motor_on: false}}
    analysis: [sync, bias, noise, drift]
    report: {{template: calibration-certificate, sign: false}}
    """)
# The steps switch the motor off, on the modbus table as on the in-process twin they are
# compared with: no servo jitter (≈ 7.5 mV RMS at the output with the motor on), so the noise
# is judged against the datasheet's own limit.
#: the runner's chunk (60 lab s) in frames (a logger block between two marks comes on top)
CHUNK_FRAMES = int(60 * FS_HZ)


def _analysis(run_dir: Path) -> dict[str, Any]:
    results: dict[str, Any] = json.loads((run_dir / "results.json").read_text())["analysis"]
    return results


def _served_rig(tmp_path: Path, port: int, group: str) -> Path:
    rig = tmp_path / "rig.yaml"
    rig.write_text(
        f"turntable: {{plugin: modbus, host: 127.0.0.1, port: {port}, "
        f"envelope: {{log_capacity_samples: {HEAD_SAMPLES}}}}}\n"
        f"daq: {{plugin: can, interface: udp_multicast, channel: '{group}'}}\n"
        "chamber: {plugin: none}\n")
    return rig


def test_long_static_step_through_can_matches_the_in_process_twin(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    pytest.importorskip("msgpack", reason="python-can's udp_multicast needs msgpack")
    if sys.platform != "linux":
        pytest.skip("udp_multicast group isolation is a Linux option")
    procedure = tmp_path / "long.yaml"
    procedure.write_text(PROCEDURE)
    runner = CliRunner()
    in_process = runner.invoke(app, ["run", str(procedure), "--out", str(tmp_path / "twin"),
                                     "--no-progress"])
    assert in_process.exit_code == 0, in_process.output

    group = multicast_group(31)
    server = SimServerProcess("modbus", args=("--can-interface", "udp_multicast",
                                              "--can-channel", group),
                              env={**os.environ, FRAME_RATE_ENV: str(PACE_HZ)}).start()
    daqs: list[CanDaq] = []
    real_build = session.build_rig

    def keep_daq(*args: Any, **kwargs: Any) -> Any:
        rig = real_build(*args, **kwargs)
        daqs.append(rig.daq)
        return rig

    monkeypatch.setattr(session, "build_rig", keep_daq)
    try:
        rig = _served_rig(tmp_path, server.port, group)
        checked = runner.invoke(app, ["validate", str(procedure), "--rig", str(rig)])
        assert checked.exit_code == 0, checked.output  # accepted: the CAN logger streams
        result = runner.invoke(app, ["run", str(procedure), "--rig", str(rig), "--out",
                                     str(tmp_path / "can"), "--no-progress"])
    finally:
        server.stop()
    assert result.exit_code == 0, result.output

    served, twin = _analysis(tmp_path / "can"), _analysis(tmp_path / "twin")
    for sync in served["sync"]["steps"]:
        # the clocks are fitted on the head's edges: 20 s of a 90 s record (+ lead and lag)
        assert sync["fit_coverage"] == pytest.approx(HEAD_SAMPLES / FS_HZ / RECORD_S, rel=0.03)
    for name, value in (("bias", "bias_v"), ("noise", "rms_max_v")):
        got, ref = served[name]["v_sz"], twin[name]["v_sz"]
        assert abs(got[value] - ref[value]) <= got["expanded_uncertainty"], (name, got, ref)
    assert served["noise"]["v_sz"]["record_s"] == pytest.approx(RECORD_S, rel=1e-3)
    model = realistic_rig_model(SensorDatasheet(model="sr207"))
    bias = served["bias"]["v_sz"]
    assert abs(bias["bias_v"] - bias_truth_v(model, "v_sz", 22.0)) <= bias["expanded_uncertainty"]
    # bounded memory: the plugin held one runner chunk and one logger block at most, never
    # a 90 000-frame record
    peak = max(d.peak_buffered_frames for d in daqs if isinstance(d, CanDaq))
    assert 0 < peak <= CHUNK_FRAMES + 2 * CHUNK_MARK_FRAMES
