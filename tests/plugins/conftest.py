"""Fixtures shared by the plugin tests in several folders: the files of an ``aatest run`` of
one sine step through the ``modbus`` table and the ``can`` logger, against an ``aatest
sim-server modbus`` in another process (:class:`aatest.testing.sim_process.SimServerProcess`)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest

CROSS_PROCESS_PROCEDURE = """\
procedure: cross-process
sensor: {model: sr207, serial: "A1234"}
rig: {turntable: sim, daq: sim, chamber: none}
sampling: {rate_hz: 2000, samples: 8000, settle_s: 1}
steps:
  - sine: {axis: inner, frequency_hz: 1.0, accel_dps2: 400, snap: coherent}
analysis: [sync, reference, scale_factor]
report: {template: calibration-certificate, sign: false}
"""


@pytest.fixture
def cross_process_run() -> Callable[[Path, int, str], tuple[Path, Path]]:
    """``write(work, port, group)`` → (procedure, rig file) in ``work``: the procedure above and
    a rig of the modbus table at ``127.0.0.1:port`` and the can logger on udp_multicast
    ``group``. One 8000-sample sine step recovers the twin's scale factor within 1 %."""

    def write(work: Path, port: int, group: str) -> tuple[Path, Path]:
        work.mkdir(parents=True, exist_ok=True)
        (work / "p.yaml").write_text(CROSS_PROCESS_PROCEDURE)
        (work / "rig.yaml").write_text(
            f"turntable: {{plugin: modbus, host: 127.0.0.1, port: {port}}}\n"
            f"daq: {{plugin: can, interface: udp_multicast, channel: '{group}'}}\n")
        return work / "p.yaml", work / "rig.yaml"

    return write
