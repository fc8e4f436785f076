"""Validation never touches hardware: ``validate``/``plan`` only construct the rig and read its
envelope; ``run`` sends ``safe_stop`` and ``close`` only to plugins it started.

The controller is a recording fake installed as a real distribution (a ``.dist-info`` on
``sys.path``, discovered through entry points like any vendor package). It copies what a vendor
copies from the guide — ``close()`` calls ``safe_stop()`` — and journals every call that would be
traffic to a controller; a second test points the real Modbus driver at a loopback port whose
connections are counted.
"""

from __future__ import annotations

import importlib
import json
import socket
import sys
import threading
from collections.abc import Iterator
from pathlib import Path
from types import ModuleType
from typing import Any

import pytest
from typer.testing import CliRunner

from aatest.cli import app

PROCEDURE = """\
procedure: life-cycle
sensor: {model: sr207, serial: "L1"}
sampling: {rate_hz: 2000, samples: 4096, settle_s: 0.5}
steps:
  - sine: {axis: inner, frequency_hz: 2.0, accel_dps2: 100, snap: coherent}
analysis: [sync, frf]
report: {template: frequency-response, sign: false}
"""

#: a vendor's table: the built-in simulator behind a journal of every controller call
PLUGIN = '''
from aatest.engine import registry

JOURNAL = []


class JournalTable:
    Config = registry.load("turntable", "sim").target.Config

    def __init__(self, config, context):
        sim = registry.load("turntable", "sim")
        self._controller = sim.target(config, context)

    def envelope(self):
        return self._controller.envelope()

    def _send(self, what, *args):
        JOURNAL.append(what)
        return getattr(self._controller, what)(*args)

    def start(self):
        self._send("start")

    def move_to(self, inner_deg, outer_deg):
        self._send("move_to", inner_deg, outer_deg)

    def begin_motion(self, step):
        self._send("begin_motion", step)

    def record(self, step):
        return self._send("record", step)

    def end_motion(self):
        self._send("end_motion")

    def safe_stop(self):
        self._send("safe_stop")

    def close(self):  # as the guide's example: leave the table safe, then release it
        self.safe_stop()
        JOURNAL.append("close")
'''


@pytest.fixture
def journal_table(tmp_path_factory: pytest.TempPathFactory,
                  monkeypatch: pytest.MonkeyPatch) -> Iterator[ModuleType]:
    """The journalling turntable installed as distribution ``acme-journal``; its module."""
    site = tmp_path_factory.mktemp("site")
    (site / "acme_journal_table.py").write_text(PLUGIN)
    info = site / "acme_journal-0.1.0.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: acme-journal\nVersion: 0.1.0\n")
    (info / "entry_points.txt").write_text(
        "[aatest.turntables]\njournal = acme_journal_table:JournalTable\n")
    monkeypatch.syspath_prepend(str(site))
    module = importlib.import_module("acme_journal_table")
    yield module
    sys.modules.pop("acme_journal_table", None)


def _files(tmp_path: Path, turntable: str, daq: str = "{plugin: sim}") -> tuple[Path, Path]:
    procedure = tmp_path / "procedure.yaml"
    procedure.write_text(PROCEDURE)
    rig = tmp_path / "rig.yaml"
    rig.write_text(f"turntable: {turntable}\ndaq: {daq}\nchamber: {{plugin: none}}\n")
    return procedure, rig


def test_validate_and_plan_send_the_controller_nothing(journal_table: ModuleType,
                                                       tmp_path: Path) -> None:
    procedure, rig = _files(tmp_path, "{plugin: journal}")
    for command in (["validate"], ["plan"], ["plan", "--json"]):
        result = CliRunner().invoke(app, [*command, str(procedure), "--rig", str(rig)])
        assert result.exit_code == 0, result.output
    assert journal_table.JOURNAL == []  # no start, no safe_stop, no close: nothing on the wire


def test_run_stops_and_closes_the_table_only_after_starting_it(journal_table: ModuleType,
                                                               tmp_path: Path) -> None:
    procedure, rig = _files(tmp_path, "{plugin: journal}")
    result = CliRunner().invoke(app, ["run", str(procedure), "--rig", str(rig), "--out",
                                      str(tmp_path / "run"), "--no-progress", "--seed", "2"])
    assert result.exit_code == 0, result.output
    calls = journal_table.JOURNAL
    assert calls[0] == "start"
    assert calls[1:5] == ["move_to", "begin_motion", "record", "end_motion"]
    # the engine's safe stop, then close (which, copied from the guide, stops once more)
    assert calls[5:] == ["safe_stop", "safe_stop", "close"]


def test_a_table_is_not_touched_when_the_rig_fails_before_it_starts(
        journal_table: ModuleType, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from aatest.engine.errors import RigFault
    from aatest.plugins.daq.sim import SimDaq

    def dead(self: SimDaq) -> None:
        raise RigFault("sim DAQ: logger does not answer")

    monkeypatch.setattr(SimDaq, "start", dead)
    procedure, rig = _files(tmp_path, "{plugin: journal}")
    result = CliRunner().invoke(app, ["run", str(procedure), "--rig", str(rig), "--out",
                                      str(tmp_path / "run"), "--no-progress"])
    assert result.exit_code == 3 and "logger does not answer" in result.output, result.output
    assert journal_table.JOURNAL == []  # the DAQ starts before the table: the table never did


class _CountingPort:
    """A loopback port that accepts connections and counts them (never answers)."""

    def __init__(self) -> None:
        self.accepted = 0
        self._listener = socket.create_server(("127.0.0.1", 0))
        self.port = int(self._listener.getsockname()[1])
        threading.Thread(target=self._accept, daemon=True).start()

    def _accept(self) -> None:
        while True:
            try:
                conn, _ = self._listener.accept()
            except OSError:
                return
            self.accepted += 1
            conn.close()

    def close(self) -> None:
        self._listener.close()


def test_validate_with_the_modbus_driver_opens_no_connection(tmp_path: Path) -> None:
    port = _CountingPort()
    try:
        procedure, rig = _files(tmp_path, f"{{plugin: modbus, host: 127.0.0.1, port: "
                                          f"{port.port}, timeout_s: 0.5, retries: 0}}",
                                 "{plugin: can, interface: virtual, channel: life-cycle}")
        for command in ("validate", "plan"):
            result = CliRunner().invoke(app, [command, str(procedure), "--rig", str(rig)])
            assert result.exit_code == 0, result.output
        # the same listener does count a driver that connects
        probe = socket.create_connection(("127.0.0.1", port.port), timeout=1.0)
        probe.close()
        deadline = threading.Event()
        for _ in range(100):
            if port.accepted:
                break
            deadline.wait(0.01)
        assert port.accepted == 1
    finally:
        port.close()


def test_a_resumed_run_must_continue_on_the_table_it_was_recorded_on(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from aatest.engine.errors import RigFault
    from aatest.plugins.turntable.sim import SimTurntable

    procedure = tmp_path / "procedure.yaml"
    procedure.write_text(PROCEDURE.replace(
        "  - sine:", "  - sine: {axis: inner, frequency_hz: 1.0, accel_dps2: 100, snap: coherent}"
                     "\n  - sine:"))
    real_begin = SimTurntable.begin_motion

    def stop_before_the_second(self: SimTurntable, step: Any) -> None:
        if step.id.startswith("s002"):
            raise RigFault("simulated table: controller stopped answering")
        real_begin(self, step)

    monkeypatch.setattr(SimTurntable, "begin_motion", stop_before_the_second)
    out = tmp_path / "run"
    args = ["run", str(procedure), "--out", str(out), "--no-progress", "--seed", "1"]
    assert CliRunner().invoke(app, args).exit_code == 3
    monkeypatch.setattr(SimTurntable, "begin_motion", real_begin)
    other = tmp_path / "other-table.yaml"
    other.write_text("turntable: {plugin: sim, serial: SIM-2}\n")
    result = CliRunner().invoke(app, [*args, "--resume", "--rig", str(other)])
    assert result.exit_code == 3, result.output
    assert ("the table identifies as serial 'SIM-2', but this run was recorded on "
            "'digital-twin': resume it on that table") in result.output
    result = CliRunner().invoke(app, [*args, "--resume"])
    assert result.exit_code == 0, result.output
    meta = json.loads((out / "results.json").read_text())["metadata"]
    assert meta["table_serial"] == "digital-twin"
    assert meta["rig"]["capabilities"]["turntable"]["declared"]["serial"] == "digital-twin"
