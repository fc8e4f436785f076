"""The pieces every conformance check shares: the simulator rig, the plugin under test, a step.

Both the turntable and chamber checks (:mod:`aatest.testing.conformance`) and the DAQ checks
(:mod:`aatest.testing.daq_conformance`) build on these; they live apart from either so that
the fault check can hand a DAQ to the DAQ checks without the two modules importing each other.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from aatest.engine import registry
from aatest.engine.errors import RigFault
from aatest.engine.interfaces import RigContext
from aatest.engine.steps import PlannedStep
from aatest.rig_defaults import LOG_RATE_HZ


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
    partner
        DAQs only: builds the (unstarted) turntable plugin the DAQ records beside, pointed at
        the same simulator; the kit starts it and records each step with it as the runner
        does. ``None``: the DAQ logs on its own (the kit waits the step's duration).
    bad_options
        Option sets the plugin's ``Config`` must refuse (beside an unknown option, which the
        kit always tries).
    """

    options: dict[str, Any]
    faults: dict[str, Callable[[], None]]
    recover: Callable[[], None]
    is_safe: Callable[[], bool]
    close: Callable[[], None]
    context: RigContext | None = None
    trigger: Callable[[], None] = field(default=lambda: None)
    fault_timeout_s: float = 10.0
    partner: Callable[[], Any] | None = None
    bad_options: tuple[dict[str, Any], ...] = ()


def build(kind: str, name: str, rig: ConformanceRig) -> Any:
    """The plugin, configured for ``rig`` (construction must not do I/O)."""
    info = registry.load(kind, name)
    return info.target(registry.configure(info, rig.options), rig.context)


def short_step(kind: str = "static", **extra: Any) -> PlannedStep:
    """A 0.5 s step at 2 kHz (``extra``: sine/rate parameters)."""
    return PlannedStep(id=f"conformance-{kind}", kind=kind, samples=1000,
                       sample_rate_hz=LOG_RATE_HZ, settle_s=0.1, **extra)


def until_fault(action: Callable[[], Any], timeout_s: float) -> RigFault:
    started = time.monotonic()
    try:
        action()
    except RigFault as exc:
        elapsed = time.monotonic() - started
        assert elapsed <= timeout_s, f"the fault took {elapsed:.1f} s (> {timeout_s:g} s)"
        assert "\n" not in str(exc), "a rig fault is one line"
        return exc
    raise AssertionError("the injected fault did not raise RigFault")
