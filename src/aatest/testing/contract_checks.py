"""The contract checks as pytest tests (collected by ``--aatest-plugin``; see
:mod:`aatest.testing.plugin`). Each test gets a fresh simulator rig."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import Any

import pytest

from aatest.testing import conformance as c
from aatest.testing import daq_conformance as d


def _kind(kind: str) -> Callable[[Callable[..., Any]], Callable[..., Any]]:
    def mark(function: Callable[..., Any]) -> Callable[..., Any]:
        function.kind = kind  # type: ignore[attr-defined]
        return function

    return mark


@pytest.fixture
def aatest_rig(aatest_spec: str) -> Iterator[tuple[str, str, c.ConformanceRig]]:
    try:
        kind, name, factory = c.load_rig(aatest_spec)
    except ValueError as exc:
        pytest.fail(str(exc), pytrace=False)
    rig = factory()
    yield kind, name, rig
    rig.close()


Rig = tuple[str, str, c.ConformanceRig]


def _check_of(kind: str, check: Callable[[str, c.ConformanceRig], None],
              ) -> Callable[[Rig], None]:
    """A test running ``check(name, rig)`` for the plugins of one kind."""

    def test(aatest_rig: Rig) -> None:
        check(aatest_rig[1], aatest_rig[2])

    test.__doc__ = check.__doc__
    return _kind(kind)(test)


test_table_life_cycle = _check_of("turntable", c.check_table_life_cycle)
test_table_refuses_beyond_its_envelope = _check_of("turntable", c.check_table_envelope)
test_chamber_life_cycle = _check_of("chamber", c.check_chamber_life_cycle)
test_daq_record_channels_clock_trigger_and_pulse = _check_of("daq", d.check_daq_record)
test_daq_life_cycle = _check_of("daq", d.check_daq_life_cycle)


def test_refuses_bad_options(aatest_rig: Rig) -> None:
    kind, name, rig = aatest_rig
    c.check_refuses_bad_options(kind, name, rig)


def test_reports_simulated(aatest_rig: Rig) -> None:
    kind, name, rig = aatest_rig
    c.check_simulated_flag(kind, name, rig)


def test_every_fault_ends_safe_and_resumes(aatest_rig: Rig) -> None:
    """Each declared fault in turn, on a fresh simulator (the rig's own faults list)."""
    kind, name, rig = aatest_rig
    assert rig.faults, f"{kind}:{name}: its conformance rig declares no faults to test"
    spec = f"{kind}:{name}"
    first = True
    for fault in list(rig.faults):
        current = rig if first else c.load_rig(spec)[2]()
        first = False
        try:
            c.check_fault(kind, name, current, fault)
        finally:
            if current is not rig:
                current.close()
