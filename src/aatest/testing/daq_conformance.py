"""The DAQ (sensor logger) part of the plugin contract, checked against the logger's simulator.

A DAQ is checked the way the runner drives it: ``channels()`` before anything connects, then
``start``, and per step the partner table's ``move_to``/``begin_motion``, the DAQ's
``start_logging``, the table's ``record``, the DAQ's ``stop_logging`` and the table's
``end_motion`` (:attr:`~aatest.testing.conformance.ConformanceRig.partner`; without a partner
the kit waits the step's duration between the two DAQ calls). On the log it returns:

- channels: exactly the declared ``channels()``, in order; each sensor channel ``v_*`` in
  volts, then ``sync_pulse``, ``trigger``, ``temperature_c`` (docs/vendor-plugins.md);
- clock: a positive nominal sample rate, finite time stamps that strictly increase, a median
  interval within 1 % of the nominal one, and — beside a table — a record at least as long as
  the table's (the DAQ log covers the table log on both sides);
- trigger: 0/1, low when logging starts, one rising edge, never falling again in the record;
- freeze pulse: 0/1 with edges during the record; beside a table, the table logs the same
  pulse (its edge period within two samples of the DAQ's) and, when the table declares a
  pulse latch, latches each edge (``fp_latch_s`` on each rising-edge row: the time since the
  true edge, finite, ≥ 0 and within half a pulse period), else leaves it all NaN.

Life cycle: two records in a row on one instance; ``close`` after ``start`` releases the
logger; a ``start`` that fails (the simulator is down) raises :class:`RigFault` in time and a
``close`` after it does not raise (the engine closes what it tried to start).
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from aatest.engine.logs import DAQ_AUX_CHANNELS, SampledLog
from aatest.engine.steps import PlannedStep
from aatest.testing.conformance_rig import ConformanceRig, build, short_step, until_fault

#: the median sample interval may differ from the nominal one by this much (a logger's crystal
#: is within 100 ppm; 1 % leaves room for a rate stated to three digits)
RATE_TOLERANCE = 0.01
#: a period needs this many rising edges (two intervals) to be a median, not one sample
MIN_PULSE_EDGES = 3


def started_partner(rig: ConformanceRig) -> Any:
    """The rig's partner table, started (``None`` when the DAQ logs on its own)."""
    if rig.partner is None:
        return None
    table = rig.partner()
    table.start()
    return table


def run_daq_step(daq: Any, table: Any, step: PlannedStep) -> tuple[SampledLog, SampledLog | None]:
    """One recorded step as the runner does it: (DAQ log, table log or None)."""
    if table is not None:
        table.move_to(0.0, 0.0)
        table.begin_motion(step)
    daq.start_logging(step)
    if table is not None:
        table_log = table.record(step)
    else:
        table_log = None
        time.sleep(step.samples / step.sample_rate_hz)
    log = daq.stop_logging()
    if table is not None:
        table.end_motion()
    return log, table_log


def stop_partner(table: Any) -> None:
    if table is not None:
        table.safe_stop()
        table.close()


def check_declared_channels(daq: Any) -> list[str]:
    """``channels()`` (no I/O): sensor volts ``v_*`` first, then the auxiliary channels."""
    declared = list(daq.channels())
    assert len(set(declared)) == len(declared), f"channels() repeats a name: {declared}"
    sensors = declared[:len(declared) - len(DAQ_AUX_CHANNELS)]
    assert sensors and all(ch.startswith("v_") for ch in sensors), \
        f"channels() must start with the sensor volts v_*: {declared}"
    assert declared[len(sensors):] == list(DAQ_AUX_CHANNELS), \
        f"channels() must end with {', '.join(DAQ_AUX_CHANNELS)}: {declared}"
    return declared


def check_log_channels(log: SampledLog, declared: list[str]) -> None:
    assert log.source == "daq", f"the DAQ log's source is {log.source!r}, not 'daq'"
    assert list(log.channels) == declared, \
        f"the log's channels {list(log.channels)} are not the declared {declared}"
    wrong = {ch: log.units.get(ch) for ch in declared
             if log.units.get(ch) != DAQ_AUX_CHANNELS.get(ch, "V")}
    assert not wrong, f"channel units {wrong}: sensor channels are 'V', " \
                      f"the others {DAQ_AUX_CHANNELS}"


def check_clock(log: SampledLog, table_log: SampledLog | None) -> None:
    """Nominal rate, finite strictly increasing time stamps, interval, coverage."""
    rate_hz = log.sample_rate_hz
    assert np.isfinite(rate_hz) and rate_hz > 0, f"sample rate {rate_hz} Hz"
    time_s = np.asarray(log.time_s)
    assert time_s.size > 1, f"the DAQ log has {time_s.size} samples"
    assert np.isfinite(time_s).all(), "the DAQ log has non-finite time stamps"
    steps = np.diff(time_s)
    assert (steps > 0).all(), \
        f"time stamps are not strictly increasing ({int((steps <= 0).sum())} steps ≤ 0)"
    interval = float(np.median(steps))
    assert abs(interval * rate_hz - 1.0) <= RATE_TOLERANCE, \
        f"median sample interval {interval * 1e3:.4g} ms, nominal {1e3 / rate_hz:.4g} ms"
    if table_log is not None:
        daq_span, table_span = time_s[-1] - time_s[0], table_log.time_s[-1] - table_log.time_s[0]
        assert daq_span >= table_span, \
            f"the DAQ record ({daq_span:.3f} s) does not cover the table log ({table_span:.3f} s)"


def _binary(log: SampledLog, channel: str) -> np.ndarray:
    values = np.asarray(log[channel], dtype=float)
    assert np.isin(values, (0.0, 1.0)).all(), f"{channel} is not 0/1 throughout"
    return values


def check_trigger(log: SampledLog) -> None:
    """Low at the start of logging, one rising edge, high to the end."""
    trigger = _binary(log, "trigger")
    edges = np.diff(trigger)
    assert trigger[0] == 0.0, "the trigger is high when logging starts (it must rise later)"
    assert (edges > 0).sum() == 1, f"the trigger rises {(edges > 0).sum()} times, not once"
    assert not (edges < 0).any(), "the trigger falls during the record"


def _pulse_period_s(time_s: np.ndarray, pulse: np.ndarray) -> float | None:
    rising = np.flatnonzero(np.diff(pulse) > 0)
    return float(np.median(np.diff(time_s[rising]))) if rising.size >= MIN_PULSE_EDGES else None


def check_freeze_pulse(log: SampledLog, table_log: SampledLog | None, latch: bool | None) -> None:
    """The DAQ drives the pulse; a table beside it logs it and latches it as it declares."""
    pulse = _binary(log, "sync_pulse")
    period = _pulse_period_s(np.asarray(log.time_s), pulse)
    assert period is not None, "the sync pulse has fewer than three rising edges in the record"
    if table_log is None:
        return
    seen = _pulse_period_s(np.asarray(table_log.time_s), np.asarray(table_log["sync_pulse"]))
    assert seen is not None, "the table logged no sync pulse from the DAQ"
    two_samples = 2.0 / min(log.sample_rate_hz, table_log.sample_rate_hz)
    assert abs(seen - period) <= two_samples, (f"the table sees a pulse period of "
                                               f"{seen * 1e3:.4g} ms, the DAQ drives "
                                               f"{period * 1e3:.4g} ms")
    latches = np.asarray(table_log["fp_latch_s"], dtype=float)
    if not latch:
        assert np.isnan(latches).all(), "a table without a pulse latch reports latch times"
        return
    # on each row where the table registered a rising edge: the time since the true edge
    on_edges = latches[np.flatnonzero(np.diff(np.asarray(table_log["sync_pulse"])) > 0) + 1]
    assert np.isfinite(on_edges).all(), \
        f"the table declares a pulse latch but {int(np.isnan(on_edges).sum())} of " \
        f"{on_edges.size} edges are not latched"
    assert ((on_edges >= 0) & (on_edges < period / 2)).all(), \
        f"latch times {on_edges.min():.4g}…{on_edges.max():.4g} s are not within half a pulse " \
        f"period after their edge"


def table_latches(table: Any) -> bool | None:
    capabilities = getattr(table, "capabilities", None)
    return None if capabilities is None else capabilities().pulse_latch


def check_daq_record(name: str, rig: ConformanceRig) -> None:
    """One recorded step: channels, clock, trigger and freeze pulse (module docstring)."""
    daq = build("daq", name, rig)
    declared = check_declared_channels(daq)
    table = started_partner(rig)
    try:
        daq.start()
        log, table_log = run_daq_step(daq, table, short_step())
    finally:
        daq.close()
        stop_partner(table)
    check_log_channels(log, declared)
    check_clock(log, table_log)
    check_trigger(log)
    check_freeze_pulse(log, table_log, table_latches(table) if table is not None else None)


def check_daq_life_cycle(name: str, rig: ConformanceRig) -> None:
    """Two records on one instance; a failed start (simulator down) then ``close`` is clean."""
    daq = build("daq", name, rig)
    table = started_partner(rig)
    try:
        daq.start()
        lengths = [len(run_daq_step(daq, table, short_step())[0]) for _ in range(2)]
        assert min(lengths) > 0, f"record lengths {lengths}: the second record is empty"
    finally:
        daq.close()
        stop_partner(table)
    if "dies" not in rig.faults:
        return
    rig.faults["dies"]()
    try:
        failing = build("daq", name, rig)
        try:
            until_fault(failing.start, rig.fault_timeout_s)
        except AssertionError as exc:
            raise AssertionError(f"start with the simulator down ('dies'): {exc}") from None
        failing.close()  # the engine closes a DAQ whose start raised: must not raise
    finally:
        rig.recover()


def check_daq_fault(name: str, rig: ConformanceRig, fault: str) -> None:
    """``fault`` while the DAQ logs: its own call raises RigFault in time, ``close`` does not
    raise, and once the fault is removed a fresh instance records again."""
    daq = build("daq", name, rig)
    table = started_partner(rig)
    step = short_step()
    try:
        daq.start()
        if table is not None:
            table.move_to(0.0, 0.0)
            table.begin_motion(step)
        rig.faults[fault]()

        def logs() -> None:  # only DAQ calls: the fault must be reported by the DAQ itself
            daq.start_logging(step)
            daq.stop_logging()

        until_fault(logs, rig.fault_timeout_s)
    finally:
        daq.close()
        if table is not None:
            table.safe_stop()
    rig.recover()
    stop_partner(table)
    resumed = build("daq", name, rig)
    table = started_partner(rig)
    try:
        resumed.start()
        log, _ = run_daq_step(resumed, table, short_step())
        assert len(log) > 0, f"after {fault}: the resumed DAQ recorded nothing"
    finally:
        resumed.close()
        stop_partner(table)
