"""The run's simulated parts and the unit's serial, decided once the rig has started."""

from __future__ import annotations

from typing import Any

import pytest

from aatest.engine.errors import InputError
from aatest.engine.run.runner import declare_simulation
from aatest.engine.steps import Plan, SensorRef


class _Recorder:
    def __init__(self, meta: dict[str, Any]) -> None:
        self.run_metadata = dict(meta)

    def amend_run_metadata(self, updates: dict[str, Any]) -> None:
        self.run_metadata.update(updates)


class _Rig:
    def __init__(self, *parts: str) -> None:
        self.parts = list(parts)

    def simulated_parts(self) -> list[str]:
        return self.parts


def _plan(serial: str | None) -> Plan:
    sensor = SensorRef(model="sr207", serial=serial) if serial else SensorRef(model="sr207")
    return Plan(procedure="p", sensor=sensor, steps=[])


def _declare(serial: str | None, recorded: str | None, *parts: str,
             stored_parts: list[str] | None = None) -> tuple[list[str], _Recorder]:
    meta: dict[str, Any] = {"sensor": {"model": "sr207", "serial": recorded or "unknown"}}
    if stored_parts is not None:
        meta["simulated_parts"] = stored_parts
    recorder = _Recorder(meta)
    return declare_simulation(_plan(serial), _Rig(*parts), recorder), recorder  # type: ignore[arg-type]


def test_a_real_rig_needs_a_named_unit() -> None:
    with pytest.raises(InputError, match=r"no unit serial .* --serial SN"):
        _declare(None, None)
    assert _declare("SN1", "SN1")[0] == []
    assert _declare(None, None, "turntable:sim")[0] == ["turntable:sim"]  # a simulation may


def test_a_resumed_run_keeps_its_unit_and_its_simulated_parts() -> None:
    assert _declare(None, "SN1")[0] == []  # resumed without --serial: the recorded unit
    with pytest.raises(InputError, match="records unit 'SN1'; it cannot be resumed as 'SN2'"):
        _declare("SN2", "SN1")
    parts, recorder = _declare("SN1", "SN1", stored_parts=["daq:can"])  # now a real logger
    assert parts == ["daq:can"] and recorder.run_metadata["simulated_parts"] == ["daq:can"]
