"""The conformance kit (``pytest --aatest-plugin KIND:NAME``) on aatest's own drivers, and
proof that it fails a plugin that breaks the contract."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from aatest.testing import conformance as c
from aatest.testing.rigs import acutrol


def test_acutrol_espec_and_simserv_pass_the_kit(tmp_path: Path) -> None:
    result = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-n", "0",
         "--aatest-plugin", "turntable:acutrol", "--aatest-plugin", "chamber:espec",
         "--aatest-plugin", "chamber:simserv"],
        cwd=tmp_path, capture_output=True, text=True, timeout=600, check=False)
    assert result.returncode == 0, result.stdout + result.stderr
    # table: life cycle, envelope, options, simulated, faults; chambers: life cycle, options,
    # simulated, faults
    assert "13 passed" in result.stdout, result.stdout


def test_modbus_and_can_pass_the_kit_against_a_separate_sim_server(tmp_path: Path) -> None:
    """Each check starts `aatest sim-server modbus` in a process of its own (the CAN logger on
    a udp_multicast group of its own), as a lab's controller is another machine."""
    pytest.importorskip("msgpack", reason="python-can's udp_multicast needs msgpack")
    if sys.platform != "linux":
        pytest.skip("SIGSTOP/SIGKILL faults and IP_MULTICAST_ALL are Linux here")
    result = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-n", "0", "-rA",
         "--aatest-plugin", "turntable:modbus", "--aatest-plugin", "daq:can"],
        cwd=tmp_path, capture_output=True, text=True, timeout=600, check=False)
    assert result.returncode == 0, result.stdout + result.stderr
    # table: life cycle, envelope, options, simulated, faults; DAQ: record, life cycle,
    # options, simulated, faults
    assert "10 passed" in result.stdout, result.stdout
    assert "::test_daq_record_channels_clock_trigger_and_pulse[daq:can]" in result.stdout


def test_unknown_plugin_is_a_clear_usage_error(tmp_path: Path) -> None:
    result = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-n", "0",
         "--aatest-plugin", "turntable:nonexistent"],
        cwd=tmp_path, capture_output=True, text=True, timeout=300, check=False)
    assert result.returncode != 0
    assert "no 'aatest.conformance' entry point named 'turntable:nonexistent'" in result.stdout


def test_a_fault_the_plugin_does_not_report_fails_the_kit() -> None:
    """A declared fault after which the table keeps working is a contract breach (here the
    'fault' does nothing, as if the driver swallowed it)."""
    rig = acutrol()
    rig.faults = {"swallowed": lambda: None}
    try:
        with pytest.raises(AssertionError, match="did not raise RigFault"):
            c.check_fault("turntable", "acutrol", rig, "swallowed")
    finally:
        rig.close()


def test_a_table_that_is_not_safe_after_safe_stop_fails_the_kit() -> None:
    rig = acutrol()
    rig.is_safe = lambda: False  # the simulator still reports the motor on
    try:
        with pytest.raises(AssertionError, match="after safe_stop the simulator is not safe"):
            c.check_table_life_cycle("acutrol", rig)
    finally:
        rig.close()
