"""The run as the station sees it: events for the browsers, prompts they answer, abort.

:class:`StationObserver` turns the step loop's events (:mod:`aatest.engine.run.events`) into
JSON messages for every connected browser. What the plots show depends on when the rig
delivers samples, and the page says which it is:

- the table's position and rate while a step runs, from its status as it is polled
  (:mod:`aatest.engine.run.status_poll`, about ten readings a second on a real table): each
  reading is published at once (``table_live``) and plotted on the table's own clock from the
  step's first reading; a table whose plugin has no ``status()`` is named on the page as one
  that reports no live status;
- a long static record on a streaming DAQ arrives in chunks while the step runs
  (:meth:`StationObserver.step_chunk`): each chunk is plotted as it arrives, decimated to
  :data:`CHUNK_POINTS` points per channel, so during a 2-hour rest the operator watches the
  sensor channels grow; the table's snapshot log follows when the step ends;
- a plugin that delivers its log only when the step ends (every recorded motion step: the
  table's controller log, the DAQ's buffer) is shown then, at once, decimated to
  :data:`PLOT_POINTS` points per channel.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from aatest.engine.errors import RunAborted
from aatest.engine.interfaces import TableStatus
from aatest.engine.logs import SampledLog
from aatest.engine.run.events import AbortFlag, PromptAnswer, utc_now
from aatest.engine.run.progress import describe
from aatest.engine.steps import Plan, PlannedStep

#: points per channel sent for one step (enough to see a dead or saturating sensor)
PLOT_POINTS = 400
#: points per channel sent for one streamed chunk (60 s of a long rest: one point per second)
CHUNK_POINTS = 60
#: what the page says about samples shown when the step has ended
AFTER_STEP = "recorded step, shown when the loggers delivered it at the step's end"
#: what the page says about a streamed record
LIVE = ("live: sensor channels as the logger delivers each chunk; the table's snapshot log "
        "when the step ends")

Publish = Callable[[dict[str, Any]], None]


def decimated(log: SampledLog, channels: list[str], points: int,
              t0_s: float | None = None) -> dict[str, list[float]]:
    """Every n-th sample of ``channels`` (and ``t`` in s from ``t0_s``, else from the log's
    start), at most ``points`` of them."""
    n = len(log)
    index = np.unique(np.linspace(0, max(n - 1, 0), num=min(points, n)).astype(int))
    t0 = t0_s if t0_s is not None else (float(log.time_s[0]) if n else 0.0)
    out = {"t": (log.time_s[index] - t0).round(6).tolist()}
    out.update({c: np.asarray(log.channels[c], dtype=float)[index].tolist() for c in channels})
    return out


def _step_json(step: PlannedStep) -> dict[str, Any]:
    return {"id": step.id, "kind": step.kind, "motion": describe(step), "prompt": step.prompt,
            "lab_duration_s": step.lab_duration_s}


def _axis(step: PlannedStep) -> str:
    """The axis a step's plots show: the one it moves (``inner`` for a static step)."""
    return step.axis if step.axis in ("inner", "outer") else "inner"


def _table_channels(step: PlannedStep, table: SampledLog) -> tuple[str, list[str]]:
    """The plotted axis and its position and acceleration channels present in ``table``."""
    axis = _axis(step)
    wanted = [f"{axis}_position_deg", f"{axis}_accel_dps2"]
    return axis, [c for c in wanted if c in table.channels]


def _sensors(daq: SampledLog) -> list[str]:
    return sorted(c for c in daq.channels if c.startswith("v_"))


@dataclass
class StationObserver:
    """A :class:`~aatest.engine.run.events.RunObserver` publishing JSON events to browsers."""

    publish: Publish
    abort: AbortFlag
    #: the streamed step being plotted live and the DAQ time (s) its plot starts at
    _live: tuple[str, float] | None = None
    #: the step whose table status is plotted and its first reading's time (s, table clock)
    _polled: tuple[str, float] | None = None

    def run_started(self, plan: Plan, done: frozenset[str]) -> None:
        """Send the step list with each step's state."""
        steps = [{**_step_json(s), "state": "done" if s.id in done else "pending"}
                 for s in plan.steps]
        self.publish({"type": "run_started", "procedure": plan.procedure, "steps": steps,
                      "started_utc": utc_now()})

    def step_started(self, step: PlannedStep) -> None:
        """Mark the step running and show its commanded motion."""
        self._live = self._polled = None
        self.publish({"type": "step", "id": step.id, "state": "running", "motion": describe(step)})

    def prompt_raised(self, step: PlannedStep) -> None:
        """Nothing to add: the station responder publishes the prompt with the orientations."""

    def step_chunk(self, step: PlannedStep, daq: SampledLog) -> None:
        """Plot a streamed chunk now, while the step runs (the first one resets the plots)."""
        if len(daq) == 0:
            return
        sensors = _sensors(daq)
        if self._live is None or self._live[0] != step.id:
            self._live = (step.id, float(daq.time_s[0]))
            axis = step.axis if step.axis in ("inner", "outer") else "inner"
            self.publish({"type": "plot_reset", "id": step.id, "axis": axis, "sensors": sensors,
                          "label": LIVE, "live": True})
        self.publish({"type": "samples", "id": step.id, "live": True,
                      "daq": decimated(daq, sensors, CHUNK_POINTS, self._live[1])})

    def step_samples(self, step: PlannedStep, table: SampledLog, daq: SampledLog) -> None:
        """Show the step's samples as soon as the loggers delivered them: after a streamed
        record only the table's log (the DAQ was plotted chunk by chunk); otherwise both logs
        at once, in one message."""
        axis, table_channels = _table_channels(step, table)
        tab = decimated(table, table_channels, PLOT_POINTS)
        if self._live is not None and self._live[0] == step.id:
            self.publish({"type": "samples", "id": step.id, "table": tab})
            return
        sensors = _sensors(daq)
        self.publish({"type": "plot_reset", "id": step.id, "axis": axis, "sensors": sensors,
                      "label": AFTER_STEP, "live": False})
        self.publish({"type": "samples", "id": step.id, "table": tab,
                      "daq": decimated(daq, sensors, PLOT_POINTS)})

    def table_status(self, step: PlannedStep, status: TableStatus) -> None:
        """Publish one polled reading of the table (called from the poll's thread): time (s)
        from the step's first reading on the table's clock, the step's axis's position (°)
        and rate (°/s)."""
        if self._polled is None or self._polled[0] != step.id:
            self._polled = (step.id, status.time_s)
        axis = _axis(step)
        position = getattr(status, f"{axis}_position_deg")
        rate = getattr(status, f"{axis}_rate_dps")
        if position is None or rate is None:  # a single-axis table asked for its outer axis
            axis, position, rate = "inner", status.inner_position_deg, status.inner_rate_dps
        self.publish({"type": "table_live", "id": step.id, "axis": axis, "clock": status.clock,
                      "t": round(status.time_s - self._polled[1], 6),
                      "position_deg": position, "rate_dps": rate})

    def table_status_unavailable(self, step: PlannedStep, reason: str) -> None:
        """Say on the page why no live table status is shown for this step."""
        self.publish({"type": "table_live_off", "id": step.id, "reason": reason})

    def step_finished(self, step: PlannedStep) -> None:
        """Mark the step done."""
        self.publish({"type": "step", "id": step.id, "state": "done"})

    def run_finished(self) -> None:
        """Every step recorded; analysis follows."""
        self.publish({"type": "analysing"})

    def run_stopped(self, reason: str) -> None:
        """The rig is safe after an abort or a fault."""
        self.publish({"type": "stopped", "reason": reason})


@dataclass
class StationResponder:
    """A :class:`~aatest.engine.run.events.PromptResponder` answered from the page."""

    publish: Publish
    abort: AbortFlag
    sensors: list[dict[str, str]]
    _answered: threading.Event = field(default_factory=threading.Event)
    _pending: str | None = None
    _who: str = ""

    def answer(self, step: PlannedStep) -> PromptAnswer:
        """Publish the instruction with each sensor's expected orientation; wait for Continue."""
        self._answered.clear()
        self._pending = step.id
        orientation = ("pivoted 180° about its sensitive axis" if step.mounting.pivoted
                       else "original orientation")
        expected = [{**s, "orientation": orientation} for s in self.sensors]
        self.publish({"type": "prompt", "id": step.id, "instruction": step.prompt,
                      "remount": step.mounting.remount, "scenario": step.mounting.scenario,
                      "sensors": expected})
        while not self._answered.wait(0.1):
            if self.abort.requested:
                self._pending = None
                raise RunAborted(f"run aborted at the prompt of {step.id}: {self.abort.reason}")
        self._pending = None
        answer = PromptAnswer(step.id, self._who, utc_now(), "station")
        self.publish({"type": "prompt_answered", **answer.as_json()})
        return answer

    def confirm(self, step_id: str, who: str) -> bool:
        """Confirm the pending prompt ``step_id`` on behalf of ``who``; False if none pending."""
        if self._pending != step_id:
            return False
        self._who = who
        self._answered.set()
        return True
