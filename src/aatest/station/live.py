"""The run as the station sees it: events for the browsers, prompts they answer, abort.

:class:`StationObserver` turns the step loop's events (:mod:`aatest.engine.run.events`) into
JSON messages for every connected browser. A recording plugin hands a step over when it has
been recorded (the twin synthesises it at once), so the live plot shows the *recorded* step,
decimated to :data:`PLOT_POINTS` points per channel and replayed over at most ``replay_s``
seconds of wall time; the page labels it as such. The abort flag is checked between replay
chunks, so an abort during a step drops that step, as a fault during recording would.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from aatest.engine.errors import RunAborted
from aatest.engine.logs import SampledLog
from aatest.engine.run.events import AbortFlag, PromptAnswer, utc_now
from aatest.engine.run.progress import describe
from aatest.engine.steps import Plan, PlannedStep

#: points per channel sent for one step (enough to see a dead or saturating sensor)
PLOT_POINTS = 400
#: messages one step's samples are split into while replaying
REPLAY_CHUNKS = 20

Publish = Callable[[dict[str, Any]], None]


def decimated(log: SampledLog, channels: list[str], points: int) -> dict[str, list[float]]:
    """Every n-th sample of ``channels`` (and ``t`` in s from the log's start), ≤ ``points``."""
    n = len(log)
    index = np.unique(np.linspace(0, max(n - 1, 0), num=min(points, n)).astype(int))
    t0 = float(log.time_s[0]) if n else 0.0
    out = {"t": (log.time_s[index] - t0).round(6).tolist()}
    out.update({c: np.asarray(log.channels[c], dtype=float)[index].tolist() for c in channels})
    return out


def _step_json(step: PlannedStep) -> dict[str, Any]:
    return {"id": step.id, "kind": step.kind, "motion": describe(step), "prompt": step.prompt,
            "lab_duration_s": step.lab_duration_s}


@dataclass
class StationObserver:
    """A :class:`~aatest.engine.run.events.RunObserver` publishing JSON events to browsers."""

    publish: Publish
    abort: AbortFlag
    replay_s: float = 2.0

    def run_started(self, plan: Plan, done: frozenset[str]) -> None:
        """Send the step list with each step's state."""
        steps = [{**_step_json(s), "state": "done" if s.id in done else "pending"}
                 for s in plan.steps]
        self.publish({"type": "run_started", "procedure": plan.procedure, "steps": steps,
                      "started_utc": utc_now()})

    def step_started(self, step: PlannedStep) -> None:
        """Mark the step running and show its commanded motion."""
        self.publish({"type": "step", "id": step.id, "state": "running", "motion": describe(step)})

    def prompt_raised(self, step: PlannedStep) -> None:
        """Nothing to add: the station responder publishes the prompt with the orientations."""

    def step_samples(self, step: PlannedStep, table: SampledLog, daq: SampledLog) -> None:
        """Replay the step's decimated samples in chunks, stopping early on abort."""
        axis = step.axis if step.axis in ("inner", "outer") else "inner"
        table_channels = [f"{axis}_position_deg", f"{axis}_accel_dps2"]
        sensors = sorted(c for c in daq.channels if c.startswith("v_"))
        tab = decimated(table, [c for c in table_channels if c in table.channels], PLOT_POINTS)
        dq = decimated(daq, sensors, PLOT_POINTS)
        self.publish({"type": "plot_reset", "id": step.id, "axis": axis, "sensors": sensors,
                      "label": "recorded step, replayed at UI pace"})
        for k in range(REPLAY_CHUNKS):
            if self.abort.requested:
                return
            part = slice(k * PLOT_POINTS // REPLAY_CHUNKS, (k + 1) * PLOT_POINTS // REPLAY_CHUNKS)
            self.publish({"type": "samples", "id": step.id,
                          "table": {c: v[part] for c, v in tab.items()},
                          "daq": {c: v[part] for c, v in dq.items()}})
            time.sleep(self.replay_s / REPLAY_CHUNKS)

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
