"""What a run tells the outside world, and what it asks of it: observers, prompts, abort.

The step loop (:mod:`aatest.engine.run.runner`) reports through a :class:`RunObserver` (the
operator's station streams these events to browsers), asks a :class:`PromptResponder` to answer
each operator prompt (re-mount, pivot, change of set), and checks an :class:`AbortFlag` between
and inside steps. An abort raises :class:`~aatest.engine.errors.RunAborted` from the loop, so it
ends through the same safe stop as a rig fault and keeps every completed step (resumable).

Nothing here moves a rig or reads a file; it only carries events. Every answer to a prompt is a
:class:`PromptAnswer` (who, when, through which channel), stored in ``run_state.json`` and in
the results metadata for the certificate's traceability (docs/interfaces.md §1).
"""

from __future__ import annotations

import sys
import threading
from dataclasses import asdict, dataclass, field
from datetime import UTC, datetime
from typing import Literal, Protocol

from aatest.engine.errors import InputError, RunAborted
from aatest.engine.logs import SampledLog
from aatest.engine.steps import Plan, PlannedStep

#: how prompts are answered: a person at a terminal or station, or ``auto`` (logged as such)
ConfirmPrompts = Literal["ask", "auto"]
#: channel an answer came through
AnswerVia = Literal["tty", "station", "auto"]


@dataclass(frozen=True)
class PromptAnswer:
    """Who confirmed an operator instruction, when (UTC, ISO 8601) and through which channel."""

    step_id: str
    answered_by: str
    answered_utc: str
    via: AnswerVia

    def as_json(self) -> dict[str, str]:
        """The answer as stored in ``run_state.json`` and the results metadata."""
        return dict(asdict(self))


def utc_now() -> str:
    """The current UTC time, ISO 8601 to the second (what answers and events carry)."""
    return datetime.now(UTC).isoformat(timespec="seconds")


class RunObserver(Protocol):
    """Receives the events of a run; called from the thread that runs the step loop."""

    def run_started(self, plan: Plan, done: frozenset[str]) -> None:
        """The rig is up; ``done`` holds the ids of steps completed earlier (resume)."""

    def step_started(self, step: PlannedStep) -> None:
        """A step begins (its prompt, if any, follows)."""

    def prompt_raised(self, step: PlannedStep) -> None:
        """The operator must act before ``step`` (the responder is asked right after)."""

    def step_samples(self, step: PlannedStep, table: SampledLog, daq: SampledLog) -> None:
        """A step was recorded; the observer may show (decimated) samples before it is kept.

        The run checks the abort flag when this returns: an abort requested meanwhile drops
        the step, as a fault during recording would.
        """

    def step_chunk(self, step: PlannedStep, daq: SampledLog) -> None:
        """A streaming DAQ delivered the next chunk of a long record, while the step runs
        (the chunk is already in the step's spool); the station plots it live."""

    def step_finished(self, step: PlannedStep) -> None:
        """A step is on disk (or a chamber step is done)."""

    # Optional (looked up with getattr; observers without them keep working), called from the
    # status poll's thread while a step runs (:mod:`aatest.engine.run.status_poll`):
    # ``table_status(step, status: TableStatus)``: a polled reading of the table's position
    # and rate; ``table_status_unavailable(step, reason: str)``: the table reports no live
    # status, or reading it failed (polling stopped for the step).

    def run_finished(self) -> None:
        """Every step is done; analysis and report follow."""

    def run_stopped(self, reason: str) -> None:
        """The run ended early (abort or fault) after the rig reached its safe state."""


class NullObserver:
    """An observer that ignores every event (the terminal run has its progress line)."""

    def run_started(self, plan: Plan, done: frozenset[str]) -> None:
        """Ignore."""

    def step_started(self, step: PlannedStep) -> None:
        """Ignore."""

    def prompt_raised(self, step: PlannedStep) -> None:
        """Ignore."""

    def step_samples(self, step: PlannedStep, table: SampledLog, daq: SampledLog) -> None:
        """Ignore."""

    def step_chunk(self, step: PlannedStep, daq: SampledLog) -> None:
        """Ignore."""

    def step_finished(self, step: PlannedStep) -> None:
        """Ignore."""

    def run_finished(self) -> None:
        """Ignore."""

    def run_stopped(self, reason: str) -> None:
        """Ignore."""


class PromptResponder(Protocol):
    """Answers an operator prompt; returns only once the instruction is confirmed."""

    def answer(self, step: PlannedStep) -> PromptAnswer:
        """Show ``step.prompt`` and wait for the confirmation (may raise RunAborted)."""
        ...


@dataclass(frozen=True)
class TtyResponder:
    """A person at the terminal confirms with Enter."""

    operator: str

    def answer(self, step: PlannedStep) -> PromptAnswer:
        """Print the instruction on stderr and wait for Enter on stdin."""
        print(f"\n>>> OPERATOR ({step.id}): {step.prompt}", file=sys.stderr)
        input("    press Enter when done ")
        return PromptAnswer(step.id, self.operator, utc_now(), "tty")


@dataclass(frozen=True)
class AutoResponder:
    """``--confirm-prompts auto``: continue at once; the certificate says nobody confirmed."""

    def answer(self, step: PlannedStep) -> PromptAnswer:
        """Log the instruction and confirm it automatically."""
        print(f"\n>>> OPERATOR ({step.id}, auto-confirmed): {step.prompt}", file=sys.stderr)
        return PromptAnswer(step.id, "nobody (--confirm-prompts auto)", utc_now(), "auto")


@dataclass
class AbortFlag:
    """Set by an operator (station button); the step loop checks it between and inside steps."""

    _event: threading.Event = field(default_factory=threading.Event)
    reason: str = ""

    def request(self, reason: str) -> None:
        """Ask the run to stop at the next check; ``reason`` says who asked and why."""
        self.reason = reason
        self._event.set()

    @property
    def requested(self) -> bool:
        """Whether an abort was asked for."""
        return self._event.is_set()

    def check(self) -> None:
        """Raise :class:`RunAborted` if an abort was requested."""
        if self._event.is_set():
            raise RunAborted(f"run aborted: {self.reason}; the rig is safe, continue with --resume")


@dataclass
class RunEvents:
    """The observer, prompt responder and abort flag one run uses."""

    observer: RunObserver = field(default_factory=NullObserver)
    responder: PromptResponder | None = None
    abort: AbortFlag = field(default_factory=AbortFlag)


def terminal_responder(
    plan: Plan, shown: list[str], operator: str, confirm: ConfirmPrompts, interactive: bool
) -> PromptResponder | None:
    """The responder of ``aatest run``; refuse before anything moves if nobody can answer.

    A prompt on a real rig is a physical change (pivot, re-mount); moving on without it
    measures the wrong thing. So without a terminal (``interactive`` False) and without
    ``--confirm-prompts auto`` a plan with unanswered prompts is refused with exit 2 before the
    rig is built; a plan without prompts needs no responder (``None``).
    """
    if confirm == "auto":
        return AutoResponder()
    if interactive:
        return TtyResponder(operator)
    pending = [s.id for s in plan.steps if s.prompt and s.id not in shown]
    if pending:
        raise InputError(
            f"the procedure has {len(pending)} operator prompt(s) (first before step "
            f"{pending[0]}) and no terminal to answer them: run it from a terminal or "
            "`aatest station`, or pass --confirm-prompts auto to confirm them unattended"
        )
    return None
