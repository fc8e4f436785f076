"""The contract every turntable, DAQ and chamber plugin must meet, checked against its simulator.

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
- ``simulated``: the plugin tells a simulator from hardware (attribute ``simulated`` True);
- options: an unknown option, and each bad option set the rig names, is refused with a
  :class:`~aatest.engine.errors.PluginError` (exit 2) naming the plugin.

The DAQ checks (declared channels, sample rate, time stamps, trigger and freeze pulse, close
after a failed start) are in :mod:`aatest.testing.daq_conformance`.
"""

from __future__ import annotations

from collections.abc import Callable
from importlib import metadata
from typing import Any

from aatest.engine import registry
from aatest.engine.errors import EXIT_BAD_INPUT, AatestError, PluginError
from aatest.engine.interfaces import RigContext, TableEnvelope
from aatest.engine.steps import PlannedStep
from aatest.testing.conformance_rig import ConformanceRig, build, short_step, until_fault
from aatest.testing.daq_conformance import check_daq_fault

# the shared pieces live in aatest.testing.conformance_rig; plugin kits import them from here
__all__ = ["GROUP", "KINDS", "ConformanceRig", "build", "check_chamber_life_cycle", "check_fault",
           "check_refuses_bad_options", "check_simulated_flag", "check_table_envelope",
           "check_table_life_cycle", "load_rig", "make_safe", "run_table_step", "short_step",
           "twin_daq_rig", "twin_rig", "until_fault"]

GROUP = "aatest.conformance"
KINDS = ("turntable", "daq", "chamber")


def load_rig(spec: str) -> tuple[str, str, Callable[[], ConformanceRig]]:
    """``"kind:name"`` → (kind, name, the rig factory its package declares)."""
    kind, _, name = spec.partition(":")
    if kind not in KINDS or not name:
        raise ValueError(f"--aatest-plugin {spec!r}: expected turntable:NAME, daq:NAME or "
                         "chamber:NAME")
    for entry in metadata.entry_points(group=GROUP):
        if entry.name == spec:
            return kind, name, entry.load()
    raise ValueError(f"--aatest-plugin {spec!r}: no '{GROUP}' entry point named {spec!r}; "
                     "the plugin's package must declare its simulator rig there")


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


def make_safe(kind: str, plugin: Any) -> None:
    """The engine's end-of-run call before ``close``: a table's safe stop, a chamber's off (a
    DAQ has none)."""
    if kind == "turntable":
        plugin.safe_stop()
    elif kind == "chamber":
        plugin.off()


def check_simulated_flag(kind: str, name: str, rig: ConformanceRig) -> None:
    plugin = build(kind, name, rig)
    start = getattr(plugin, "start", None)
    if start is not None:
        start()
    try:
        assert getattr(plugin, "simulated", None) is True, \
            "the plugin does not report simulated=True against its simulator"
    finally:
        make_safe(kind, plugin)
        plugin.close()


def check_refuses_bad_options(kind: str, name: str, rig: ConformanceRig) -> None:
    """An unknown option and each of the rig's bad option sets are a PluginError (exit 2)
    naming the plugin, never a library exception or a silently ignored key."""
    info = registry.load(kind, name)
    unknown = {**rig.options, "aatest_conformance_no_such_option": 1}
    for options in (unknown, *({**rig.options, **bad} for bad in rig.bad_options)):
        try:
            registry.configure(info, options)
        except PluginError as exc:
            assert name in str(exc), f"the refusal does not name the plugin: {exc}"
            assert exc.exit_code == EXIT_BAD_INPUT, \
                f"a bad option exits {exc.exit_code}, not {EXIT_BAD_INPUT}"
        else:
            shown = {k: v for k, v in options.items() if k not in rig.options or
                     rig.options[k] != v}
            raise AssertionError(f"bad options {shown} were accepted")


def check_fault(kind: str, name: str, rig: ConformanceRig, fault: str) -> None:
    """Inject ``fault`` mid-use: RigFault in time, safe state, then a fresh instance works."""
    if kind == "daq":
        check_daq_fault(name, rig, fault)
        return
    plugin = build(kind, name, rig)
    if kind == "turntable":
        plugin.start()
        plugin.move_to(0.0, 0.0)
        rig.faults[fault]()
        until_fault(lambda: run_table_step(plugin, rig, short_step()), rig.fault_timeout_s)
        plugin.safe_stop()
    else:
        start = getattr(plugin, "start", None)
        if start is not None:
            start()
        plugin.set_temperature(30.0)
        rig.faults[fault]()
        until_fault(lambda: plugin.wait_stable(60.0), rig.fault_timeout_s)
        plugin.off()
    rig.recover()
    # reachable again: the safe stop (the engine's, or the operator's next run) now holds
    make_safe(kind, plugin)
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


def _twin_context() -> RigContext:
    """A rig context of its own: every plugin built with it shares one twin session."""
    from aatest.engine.datasheet import SensorDatasheet
    from aatest.engine.steps import SensorRef

    return RigContext(sensor=SensorRef(model="reference"),
                      datasheet=SensorDatasheet(model="reference"))


def twin_rig(options: dict[str, Any] | None = None) -> ConformanceRig:
    """The rig of a plugin whose "simulator" is aatest's twin (a table built on the ``sim``
    turntable, like the example vendor package's): the twin is shared through the rig context,
    the kit starts its DAQ, and its one fault is a servo trip (the motor switches off by itself
    mid-run)."""
    from aatest.twin.session import twin_session

    context = _twin_context()

    def world() -> Any:  # built on first use by the plugin itself
        return twin_session(context).world

    def servo_trip() -> None:
        world().motor_on = False

    return ConformanceRig(
        options=options or {}, context=context, faults={"servo-trip": servo_trip},
        recover=lambda: None, is_safe=lambda: not world().motor_on, close=lambda: None,
        trigger=lambda: world().start_daq(), fault_timeout_s=5.0)


def twin_daq_rig(options: dict[str, Any] | None = None,
                 faults: dict[str, Callable[[], None]] | None = None,
                 recover: Callable[[], None] = lambda: None) -> ConformanceRig:
    """The rig of a DAQ plugin that records aatest's twin (one wrapping the ``sim`` DAQ): its
    partner is the ``sim`` turntable on the same twin. The twin's logger has no faults of its
    own, so the plugin's package passes the faults its own layer can produce (and ``recover``,
    which removes them)."""
    context = _twin_context()

    def partner() -> Any:
        info = registry.load("turntable", "sim")
        return info.target(registry.configure(info, {}), context)

    return ConformanceRig(
        options=options or {}, context=context, faults=dict(faults or {}), recover=recover,
        is_safe=lambda: True, close=lambda: None, partner=partner, fault_timeout_s=5.0)
