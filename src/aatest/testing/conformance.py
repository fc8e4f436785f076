"""The contract every turntable and chamber plugin must meet, checked against its simulator.

A plugin package declares, in the entry-point group ``aatest.conformance``, a factory named
``"<kind>:<plugin name>"`` that returns a :class:`ConformanceRig`: the plugin's options pointing
at a running simulator, the faults that simulator can produce on purpose, and how to read its
safe state. The checks here (run by ``pytest --aatest-plugin turntable:NAME``, see
:mod:`aatest.testing.plugin`) then exercise the plugin the way the engine does:

- life cycle: construction does no I/O; start → move → begin → record → end → safe stop →
  close; ``safe_stop``/``off`` twice and after ``close`` never raise;
- envelope: the reported envelope is a :class:`TableEnvelope`, a command beyond it is refused
  with an :class:`~aatest.engine.errors.AatestError` (refusals, never a library exception);
- faults: after every declared fault the next call raises :class:`RigFault` (one line, naming
  the plugin) within the declared time, ``safe_stop``/``off`` do not raise and the simulator
  reports the safe state (table stopped, motor off; chamber in standby);
- resume: once the fault is removed, a fresh plugin instance starts and works again;
- ``simulated``: the plugin tells a simulator from hardware (attribute ``simulated`` True).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from importlib import metadata
from typing import Any

from aatest.engine import registry
from aatest.engine.errors import AatestError, RigFault
from aatest.engine.interfaces import RigContext, TableEnvelope
from aatest.engine.steps import PlannedStep

GROUP = "aatest.conformance"


@dataclass
class ConformanceRig:
    """A plugin's simulator, as the conformance checks need it.

    Attributes
    ----------
    options
        The plugin's rig-file options pointing at the simulator.
    faults
        Fault name → a function that makes the simulator (or the link) fail from now on.
    recover
        Removes every injected fault (the operator fixed the rig).
    is_safe
        True when the simulator is in the safe state (table: motion stopped and motor off;
        chamber: standby).
    close
        Stops the simulator.
    context
        The rig context to build the plugin with (simulated plugins share their twin through it).
    trigger
        Starts the DAQ (the trigger line a table log waits for); turntables only.
    fault_timeout_s
        The longest a call may take to report an injected fault.
    """

    options: dict[str, Any]
    faults: dict[str, Callable[[], None]]
    recover: Callable[[], None]
    is_safe: Callable[[], bool]
    close: Callable[[], None]
    context: RigContext | None = None
    trigger: Callable[[], None] = field(default=lambda: None)
    fault_timeout_s: float = 10.0


def load_rig(spec: str) -> tuple[str, str, Callable[[], ConformanceRig]]:
    """``"kind:name"`` → (kind, name, the rig factory its package declares)."""
    kind, _, name = spec.partition(":")
    if kind not in ("turntable", "chamber") or not name:
        raise ValueError(f"--aatest-plugin {spec!r}: expected turntable:NAME or chamber:NAME "
                         "(the DAQ contract is not in this kit yet)")
    for entry in metadata.entry_points(group=GROUP):
        if entry.name == spec:
            return kind, name, entry.load()
    raise ValueError(f"--aatest-plugin {spec!r}: no '{GROUP}' entry point named {spec!r}; "
                     "the plugin's package must declare its simulator rig there")


def build(kind: str, name: str, rig: ConformanceRig) -> Any:
    """The plugin, configured for ``rig`` (construction must not do I/O)."""
    info = registry.load(kind, name)
    return info.target(registry.configure(info, rig.options), rig.context)


def short_step(kind: str = "static", **extra: Any) -> PlannedStep:
    """A 0.5 s step at 2 kHz (``extra``: sine/rate parameters)."""
    return PlannedStep(id=f"conformance-{kind}", kind=kind, samples=1000,
                       sample_rate_hz=2000.0, settle_s=0.1, **extra)


def run_table_step(table: Any, rig: ConformanceRig, step: PlannedStep) -> Any:
    """One recorded step the way the runner does it."""
    table.move_to(0.0, 0.0)
    table.begin_motion(step)
    rig.trigger()
    log = table.record(step)
    table.end_motion()
    return log


def check_table_life_cycle(name: str, rig: ConformanceRig) -> None:
    table = build("turntable", name, rig)
    table.start()
    assert isinstance(table.envelope(), TableEnvelope)
    log = run_table_step(table, rig, short_step())
    assert len(log) == short_step().samples, "the table log has the step's samples"
    table.safe_stop()
    assert rig.is_safe(), "after safe_stop the simulator is not safe (motor on or moving)"
    table.safe_stop()
    table.close()
    table.safe_stop()  # after close: still must not raise


def check_table_envelope(name: str, rig: ConformanceRig) -> None:
    table = build("turntable", name, rig)
    table.start()
    envelope = table.envelope()
    f_hz = 1.0
    over = 2.0 * envelope.inner.accel_dps2  # twice the acceleration limit at 1 Hz
    step = short_step("sine", axis="inner", frequency_hz=f_hz, accel_dps2=over,
                      amplitude_deg=over / (2 * 3.141592653589793 * f_hz) ** 2)
    try:
        table.move_to(0.0, 0.0)
        table.begin_motion(step)
    except AatestError:
        pass
    else:
        raise AssertionError(f"a sine of {over:g} °/s² (limit {envelope.inner.accel_dps2:g}) "
                             "was not refused")
    finally:
        table.safe_stop()
        table.close()


def check_simulated_flag(kind: str, name: str, rig: ConformanceRig) -> None:
    plugin = build(kind, name, rig)
    start = getattr(plugin, "start", None)
    if start is not None:
        start()
    try:
        assert getattr(plugin, "simulated", None) is True, \
            "the plugin does not report simulated=True against its simulator"
    finally:
        (plugin.safe_stop if kind == "turntable" else plugin.off)()
        plugin.close()


def _until_fault(action: Callable[[], Any], timeout_s: float) -> RigFault:
    started = time.monotonic()
    try:
        action()
    except RigFault as exc:
        elapsed = time.monotonic() - started
        assert elapsed <= timeout_s, f"the fault took {elapsed:.1f} s (> {timeout_s:g} s)"
        assert "\n" not in str(exc), "a rig fault is one line"
        return exc
    raise AssertionError("the injected fault did not raise RigFault")


def check_fault(kind: str, name: str, rig: ConformanceRig, fault: str) -> None:
    """Inject ``fault`` mid-use: RigFault in time, safe state, then a fresh instance works."""
    plugin = build(kind, name, rig)
    if kind == "turntable":
        plugin.start()
        plugin.move_to(0.0, 0.0)
        rig.faults[fault]()
        _until_fault(lambda: run_table_step(plugin, rig, short_step()), rig.fault_timeout_s)
        plugin.safe_stop()
    else:
        start = getattr(plugin, "start", None)
        if start is not None:
            start()
        plugin.set_temperature(30.0)
        rig.faults[fault]()
        _until_fault(lambda: plugin.wait_stable(60.0), rig.fault_timeout_s)
        plugin.off()
    rig.recover()
    # reachable again: the safe stop (the engine's, or the operator's next run) now holds
    (plugin.safe_stop if kind == "turntable" else plugin.off)()
    assert rig.is_safe(), f"after {fault}: the simulator is not in the safe state"
    plugin.close()
    resumed = build(kind, name, rig)  # resume: a new run builds the plugin again
    if kind == "turntable":
        resumed.start()
        run_table_step(resumed, rig, short_step())
        resumed.safe_stop()
    else:
        start = getattr(resumed, "start", None)
        if start is not None:
            start()
        resumed.set_temperature(25.0)
        resumed.wait_stable(0.0)
        resumed.off()
    resumed.close()


def check_chamber_life_cycle(name: str, rig: ConformanceRig) -> None:
    chamber = build("chamber", name, rig)
    start = getattr(chamber, "start", None)
    if start is not None:
        start()
    chamber.set_temperature(30.0)
    temperature = chamber.wait_stable(60.0)
    assert abs(temperature - 30.0) < 1.0, f"stable at {temperature:g} °C for a 30 °C set point"
    try:
        chamber.set_temperature(1000.0)
    except AatestError:
        pass
    else:
        raise AssertionError("a 1000 °C set point was not refused")
    chamber.off()
    assert rig.is_safe(), "after off the chamber is not in standby"
    chamber.off()
    chamber.close()
    chamber.off()  # after close: still must not raise


def twin_rig(options: dict[str, Any] | None = None) -> ConformanceRig:
    """The rig of a plugin whose "simulator" is aatest's twin (a table built on the ``sim``
    turntable, like the example vendor package's): the twin is shared through the rig context,
    the kit starts its DAQ, and its one fault is a servo trip (the motor switches off by itself
    mid-run)."""
    from aatest.engine.datasheet import SensorDatasheet
    from aatest.engine.steps import SensorRef
    from aatest.twin.session import twin_session

    context = RigContext(sensor=SensorRef(model="reference"),
                         datasheet=SensorDatasheet(model="reference"))

    def world() -> Any:  # built on first use by the plugin itself
        return twin_session(context).world

    def servo_trip() -> None:
        world().motor_on = False

    return ConformanceRig(
        options=options or {}, context=context, faults={"servo-trip": servo_trip},
        recover=lambda: None, is_safe=lambda: not world().motor_on, close=lambda: None,
        trigger=lambda: world().start_daq(), fault_timeout_s=5.0)
